import os
import shutil
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[3]


@pytest.fixture(scope="session")
def trayecto() -> str:
    """The trayecto binary: $TRAYECTO_BIN (scripts/test.sh sets it), else the repository's build."""
    b = os.environ.get("TRAYECTO_BIN")
    if b:
        assert Path(b).is_file() or shutil.which(b), f"TRAYECTO_BIN={b} does not exist"
        return b
    for p in (REPO / "target/debug/trayecto", REPO / "target/release/trayecto"):
        if p.is_file():
            return str(p)
    pytest.fail("no trayecto binary: build it (cargo build) or set TRAYECTO_BIN")


@pytest.fixture(scope="module")
def cluster():
    """A local Dask cluster with two single-threaded worker processes (with nannies, which restart
    a worker that dies)."""
    from distributed import Client, LocalCluster

    with LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None
    ) as c, Client(c) as client:
        yield c, client
