"""The ``trayecto-farm`` command: render frames on a Dask cluster (a local one by default)."""

from __future__ import annotations

import argparse
import os
import shutil
import sys
from pathlib import Path

from .farm import FarmError, FarmJob, run_farm

EPILOG = """\
Options after '--' go to 'trayecto render' unchanged (e.g. -- --width 640 --height 480 --seed 3).
Every worker needs Trayecto installed ('trayecto' on PATH, or --trayecto PATH as the workers see it)
and the scene: either at the same absolute path on every machine (a shared filesystem), or sent by
the driver with --bundle (the scene file's folder, zipped; --bundle-root chooses another folder).
"""


def parse_args(argv):
    p = argparse.ArgumentParser(
        prog="trayecto-farm",
        description="Render Trayecto frames on a Dask cluster: each frame is split into sample "
        "ranges rendered as tasks and merged exactly (bit-identical to a single render).",
        epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("scenes", nargs="+", metavar="SCENE", help="scene file(s) or built-in name(s); several scenes are several frames")
    p.add_argument("--spp", type=int, required=True, help="samples per pixel of each frame")
    p.add_argument("--chunks", type=int, default=None, help="sample ranges per frame (default: 1 with several frames, else 2 per worker thread)")
    p.add_argument("-o", "--output", type=Path, required=True, help="output image (.exr, .png, ...); with several frames out_0000.exr, out_0001.exr, ...")
    p.add_argument("--scheduler", help="address of a running Dask scheduler, e.g. tcp://host:8786 (default: start a local cluster)")
    p.add_argument("--cameras", help="comma-separated camera names or indices: one frame per camera")
    p.add_argument("--frames", help="A..B: frames A to B of the scene's animation (trayecto render --frame N each), numbered out_A.exr ... out_B.exr")
    p.add_argument("--workers", type=int, default=None, help="local cluster only: worker processes (default: 2, or 1 per core up to 4)")
    p.add_argument("--threads-per-task", type=int, default=None, help="--threads given to each renderer (default: the renderer's own choice; a local cluster divides the cores)")
    p.add_argument("--trayecto", default=os.environ.get("TRAYECTO_BIN", "trayecto"), help="the trayecto executable as the workers see it (default: $TRAYECTO_BIN or 'trayecto')")
    p.add_argument("--bundle", action="store_true", help="send the scene's folder to the workers instead of relying on a shared filesystem")
    p.add_argument("--bundle-root", type=Path, help="folder to bundle (default: the scene file's folder)")
    p.add_argument("--retries", type=int, default=2, help="times a failed chunk is retried (a chunk whose worker dies is always rescheduled)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    argv = list(argv)
    # Everything after '--' goes to the renderer (split here: argparse would take it for scenes).
    rest = []
    if "--" in argv:
        i = argv.index("--")
        argv, rest = argv[:i], argv[i + 1 :]
    a = p.parse_args(argv)
    a.render_args = rest
    return a


def main(argv=None) -> int:
    a = parse_args(sys.argv[1:] if argv is None else argv)
    try:
        import distributed  # noqa: F401
    except ImportError:
        print(
            "error: trayecto-farm needs dask.distributed: pip install 'dask[distributed]' tqdm "
            "(or pip install ./python/trayecto_farm from the Trayecto repository)",
            file=sys.stderr,
        )
        return 2
    from distributed import Client, LocalCluster

    cameras = [c.strip() for c in a.cameras.split(",")] if a.cameras else [None]
    anim_frames = [None]
    if a.frames:
        try:
            lo, hi = (int(x) for x in a.frames.split(".."))
        except ValueError:
            print(f"error: --frames must be A..B (got '{a.frames}')", file=sys.stderr)
            return 2
        if lo < 0 or hi < lo:
            print(f"error: --frames must be A..B with 0 <= A <= B (got '{a.frames}')", file=sys.stderr)
            return 2
        anim_frames = list(range(lo, hi + 1))
    frames = len(a.scenes) * len(cameras) * len(anim_frames)
    local_trayecto = a.trayecto if shutil.which(a.trayecto) or Path(a.trayecto).is_file() else None
    cluster = None
    try:
        if a.scheduler:
            if a.workers is not None:
                raise FarmError("--workers only applies to a local cluster (no --scheduler)")
            client = Client(a.scheduler, timeout="30s")
            threads = a.threads_per_task
        else:
            cores = os.cpu_count() or 1
            workers = a.workers or max(1, min(4, cores))
            if workers < 1:
                raise FarmError(f"--workers must be at least 1 (got {workers})")
            threads = a.threads_per_task or max(1, cores // workers)
            # One task per worker at a time; the renderer uses `threads` threads for it.
            cluster = LocalCluster(
                n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=None
            )
            client = Client(cluster)
        n_workers = max(1, len(client.scheduler_info().get("workers", {})))
        chunks = a.chunks or (1 if frames > 1 else 2 * n_workers)
        job = FarmJob(
            scenes=a.scenes,
            spp=a.spp,
            chunks=chunks,
            output=a.output,
            cameras=cameras,
            anim_frames=anim_frames,
            render_args=a.render_args,
            trayecto=a.trayecto,
            threads_per_task=threads,
            bundle=a.bundle,
            bundle_root=a.bundle_root,
            retries=a.retries,
        )
        if local_trayecto is None:
            raise FarmError(
                f"cannot run '{a.trayecto}' on this machine to merge the parts: put trayecto on "
                "PATH or pass --trayecto"
            )
        bar = None
        progress = None
        if not a.no_progress:
            from tqdm import tqdm

            bar = tqdm(total=len(job.tasks()), unit="chunk", desc="rendering")

            def progress(done, total):
                bar.n = done
                bar.refresh()

        try:
            outputs = run_farm(job, client, progress=progress)
        finally:
            if bar is not None:
                bar.close()
        for o in outputs:
            print(f"wrote {o}", file=sys.stderr)
        client.close()
        return 0
    except FarmError as e:
        print(f"error: {e}", file=sys.stderr)
        return 1
    except OSError as e:
        print(f"error: cannot reach the Dask cluster: {e}", file=sys.stderr)
        return 1
    finally:
        if cluster is not None:
            cluster.close()


if __name__ == "__main__":
    sys.exit(main())
