"""The Dask farm driver: a frame split into chunks on a LocalCluster, merged, is bit-identical to
a single render — also when a worker is killed while it renders a chunk."""

import os
import signal
import subprocess
import sys
import threading
import time
import zipfile
from pathlib import Path

import pytest

from trayecto_farm.farm import Bundle, FarmError, FarmJob, Task, plan_chunks, run_farm

SIZE = ["--width", "24", "--height", "16", "--seed", "3"]


def single(trayecto, tmp_path, spp, extra=(), scene="cornell", name="single.exr"):
    out = tmp_path / name
    subprocess.run(
        [trayecto, "render", scene, "-q", "--spp", str(spp), *SIZE, *extra, "-o", str(out)],
        check=True,
    )
    return out.read_bytes()


def test_sppm_is_not_split(tmp_path):
    job = FarmJob(["cornell"], 8, 2, tmp_path / "f.exr", render_args=["--integrator", "sppm"])
    with pytest.raises(FarmError, match="sppm cannot be split"):
        run_farm(job, client=None)
    FarmJob(["cornell"], 8, 2, tmp_path / "f.exr", render_args=["--integrator", "vcm"]).tasks()


def test_plan_chunks_covers_every_sample_once():
    assert plan_chunks(10, 1) == [(0, 10)]
    assert plan_chunks(10, 3) == [(0, 3), (3, 6), (6, 10)]
    assert plan_chunks(2, 5) == [(0, 1), (1, 2)]
    for spp, k in [(1, 1), (7, 3), (1000, 7), (64, 64)]:
        c = plan_chunks(spp, k)
        assert c[0][0] == 0 and c[-1][1] == spp
        assert all(a < b for a, b in c)
        assert all(c[i][1] == c[i + 1][0] for i in range(len(c) - 1))
    with pytest.raises(FarmError):
        plan_chunks(0, 2)
    with pytest.raises(FarmError):
        plan_chunks(8, 0)


def test_bundle_round_trips_and_refuses_entries_outside_it(tmp_path):
    scene_dir = tmp_path / "scene"
    (scene_dir / "tex").mkdir(parents=True)
    (scene_dir / "a.gltf").write_text("{}")
    (scene_dir / "tex" / "t.png").write_bytes(b"png")
    b = Bundle.of(scene_dir / "a.gltf")
    assert b.scene == "a.gltf"
    p = b.unpack()
    assert p.read_text() == "{}" and (p.parent / "tex" / "t.png").read_bytes() == b"png"
    assert b.unpack() == p  # unpacked once per content

    import io

    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w") as z:
        z.writestr("../../evil.txt", "x")
    bad = Bundle("0" * 64 + "evil", buf.getvalue(), "a.gltf")
    with pytest.raises(FarmError, match="outside the bundle"):
        bad.unpack()
    with pytest.raises(FarmError, match="not inside"):
        Bundle.of(scene_dir / "a.gltf", tmp_path / "elsewhere")


def test_two_workers_give_the_single_render_bit_for_bit(trayecto, tmp_path, cluster):
    _, client = cluster
    spp = 17
    want = single(trayecto, tmp_path, spp)
    seen = []
    job = FarmJob(
        scenes=["cornell"], spp=spp, chunks=5, output=tmp_path / "farm.exr",
        render_args=SIZE, trayecto=trayecto, threads_per_task=1,
    )
    [out] = run_farm(job, client, progress=lambda d, t: seen.append((d, t)))
    assert out.read_bytes() == want
    assert seen[0] == (0, 5) and seen[-1] == (5, 5)


def test_a_bundled_scene_file_renders_the_same(trayecto, tmp_path, cluster):
    _, client = cluster
    repo = Path(__file__).resolve().parents[3]
    scenes = sorted((repo / "scenes").glob("*.toml"))
    if not scenes:
        pytest.skip("no .toml scene in scenes/")
    scene = scenes[0]
    want = single(trayecto, tmp_path, 6, scene=str(scene))
    job = FarmJob(
        scenes=[str(scene)], spp=6, chunks=3, output=tmp_path / "bundled.exr",
        render_args=SIZE, trayecto=trayecto, threads_per_task=1, bundle=True,
    )
    [out] = run_farm(job, client)
    assert out.read_bytes() == want


def test_a_worker_killed_mid_render_still_gives_the_same_image(trayecto, tmp_path, cluster):
    """SIGKILL the worker process that is rendering a chunk: the scheduler reschedules the chunk on
    the other worker (the nanny restarts the dead one) and the merged image is unchanged."""
    _, client = cluster
    spp = 1600
    extra = ["--max-depth", "4"]
    want = single(trayecto, tmp_path, spp, extra)
    job = FarmJob(
        scenes=["cornell"], spp=spp, chunks=4, output=tmp_path / "killed.exr",
        render_args=SIZE + extra, trayecto=trayecto, threads_per_task=1, retries=0,
    )
    pids = client.run(os.getpid)
    killed = {}

    def killer():
        deadline = time.time() + 120
        while time.time() < deadline and not killed:
            for addr, keys in client.processing().items():
                if any(str(k).startswith("trayecto-") for k in keys) and addr in pids:
                    # Let the renderer get going, then kill the worker mid-chunk.
                    time.sleep(0.3)
                    os.kill(pids[addr], signal.SIGKILL)
                    killed[addr] = list(keys)
                    return
            time.sleep(0.02)

    t = threading.Thread(target=killer)
    t.start()
    [out] = run_farm(job, client)
    t.join()
    assert killed, "no worker was killed while it rendered a chunk"
    assert out.read_bytes() == want
    # The nanny brought a worker back.
    client.wait_for_workers(2, timeout=60)


def test_one_frame_per_task_for_several_scenes_and_cameras(trayecto, tmp_path, cluster):
    _, client = cluster
    want = single(trayecto, tmp_path, 5)
    job = FarmJob(
        scenes=["cornell", "cornell"], cameras=["0"], spp=5, chunks=1,
        output=tmp_path / "anim.exr", render_args=SIZE, trayecto=trayecto, threads_per_task=1,
    )
    outs = run_farm(job, client)
    assert [o.name for o in outs] == ["anim_0000.exr", "anim_0001.exr"]
    assert len(job.tasks()) == 2
    assert all(o.read_bytes() == want for o in outs)


def test_renderer_errors_reach_the_user(trayecto, tmp_path, cluster):
    _, client = cluster
    job = FarmJob(
        scenes=["cornell"], spp=4, chunks=2, output=tmp_path / "x.exr",
        render_args=["--max-depth", "banana"], trayecto=trayecto, retries=0,
    )
    with pytest.raises(FarmError, match="banana"):
        run_farm(job, client)
    job.render_args = []
    job.trayecto = "/nonexistent/trayecto"
    with pytest.raises(FarmError, match="cannot run"):
        run_farm(job, client)
    job.trayecto = trayecto
    job.output = tmp_path / "missing-dir" / "x.exr"
    with pytest.raises(FarmError, match="output folder"):
        run_farm(job, client)


def test_command_line_on_a_local_cluster(trayecto, tmp_path):
    want = single(trayecto, tmp_path, 9)
    out = tmp_path / "cli.exr"
    r = subprocess.run(
        [sys.executable, "-m", "trayecto_farm.cli", "cornell", "--spp", "9", "--chunks", "3",
         "--workers", "2", "--trayecto", trayecto, "--no-progress", "-o", str(out), "--", *SIZE],
        capture_output=True, text=True, timeout=300,
    )
    assert r.returncode == 0, r.stderr
    assert out.read_bytes() == want
    r = subprocess.run(
        [sys.executable, "-m", "trayecto_farm.cli", "nosuch.gltf", "--spp", "4",
         "--trayecto", trayecto, "-o", str(tmp_path / "y.exr")],
        capture_output=True, text=True, timeout=300,
    )
    assert r.returncode == 1 and "no such scene file" in r.stderr


def test_a_transparent_frame_keeps_its_alpha(trayecto, tmp_path, cluster):
    """``--transparent`` through the farm: the chunks carry the film's coverage counts, so the
    merged EXR, alpha channel included, is the single render's bit for bit."""
    _, client = cluster
    scene = tmp_path / "ball.toml"
    scene.write_text(
        '[[camera]]\neye = [0.0, 0.0, 4.0]\ntarget = [0.0, 0.0, 0.0]\nfov = 40.0\n'
        '[[object]]\ntype = "sphere"\ncenter = [0.0, 0.0, 0.0]\nradius = 0.8\n'
    )
    extra = ["--transparent"]
    want = single(trayecto, tmp_path, 6, extra=extra, scene=str(scene))
    assert b"A\x00" in want[:1000], "the single render has no alpha channel"
    job = FarmJob(
        scenes=[str(scene)], spp=6, chunks=3, output=tmp_path / "alpha.exr",
        render_args=SIZE + extra, trayecto=trayecto, threads_per_task=1,
    )
    [out] = run_farm(job, client)
    assert out.read_bytes() == want
