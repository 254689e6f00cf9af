"""Tests of the `trayecto` Python package against this checkout's command line (TRAYECTO_BIN):
every format loads, load_dict is the TOML scene, renders agree with the CLI bit for bit, AOVs,
errors, cancelling, and scenes changed and rendered again without reloading."""

import _thread
import os
import pathlib
import subprocess
import threading
import time

import numpy as np
import pytest

import trayecto

ROOT = pathlib.Path(__file__).resolve().parents[3]
SCENES = ROOT / "scenes"
BIN = os.environ.get("TRAYECTO_BIN", str(ROOT / "target" / "debug" / "trayecto"))
TINY = dict(width=24, height=24, spp=2)


def cli(*args):
    return subprocess.run([BIN, *map(str, args)], capture_output=True, text=True)


OBJ = """v -1 0 -1
v 1 0 -1
v 0 1.5 -1
vn 0 0 1
f 1//1 2//1 3//1
"""


@pytest.mark.parametrize(
    "path",
    [
        "cornell",
        SCENES / "twin" / "twin.toml",
        SCENES / "twin" / "twin.gltf",
        SCENES / "twin" / "cube.ply",
        SCENES / "gltf-files" / "box_draco.glb",
        SCENES / "pbrt" / "bump.pbrt",
        "OBJ",
    ],
    ids=lambda p: pathlib.Path(str(p)).name,
)
def test_each_format_loads_and_renders(path, tmp_path):
    if path == "OBJ":
        path = tmp_path / "tri.obj"
        path.write_text(OBJ)
    scene = trayecto.load_file(path)
    img = trayecto.render(scene, **TINY)
    a = img.numpy()
    assert a.shape == (24, 24, 3) and a.dtype == np.float32
    assert np.isfinite(a).all() and a.max() > 0


def test_fbx_error_is_the_clis(tmp_path):
    bad = tmp_path / "ascii.fbx"
    bad.write_text("; FBX 7.4.0 project file\n")
    with pytest.raises(trayecto.SceneError) as e:
        trayecto.load_file(bad)
    r = cli("render", bad, "-o", tmp_path / "x.png")
    assert r.returncode != 0
    assert r.stderr.strip() == f"error: {e.value}"


def test_missing_file_error_is_the_clis(tmp_path):
    missing = tmp_path / "nope.gltf"
    with pytest.raises(trayecto.SceneError) as e:
        trayecto.load_file(missing)
    r = cli("render", missing, "-o", tmp_path / "x.png")
    assert r.stderr.strip() == f"error: {e.value}"
    assert "no such file" in str(e.value)


@pytest.mark.parametrize(
    "flags,kw",
    [
        ([], {}),
        (
            ["--integrator", "whitted", "--sampler", "sobol", "--filter", "gaussian", "--seed", "7"],
            dict(integrator="whitted", sampler="sobol", filter="gaussian", seed=7),
        ),
        (
            ["--max-depth", "3", "--no-mis", "--rr-depth", "1", "--accel", "grid", "--threads", "1"],
            dict(max_depth=3, no_mis=True, rr_depth=1, accel="grid", threads=1),
        ),
    ],
)
def test_cornell_is_the_clis_image(flags, kw, tmp_path):
    size = ["--width", 40, "--height", 32, "--spp", 4]
    r = cli("render", "cornell", *size, *flags, "--quiet", "-o", tmp_path / "cli.exr")
    assert r.returncode == 0, r.stderr
    img = trayecto.render(trayecto.load_file("cornell"), width=40, height=32, spp=4, **kw)
    assert img.numpy().shape == (32, 40, 3)
    img.write(tmp_path / "py.exr")
    assert (tmp_path / "py.exr").read_bytes() == (tmp_path / "cli.exr").read_bytes()


def test_png_and_repr_png_match_the_clis(tmp_path):
    r = cli("render", "cornell", "--width", 16, "--height", 16, "--spp", 2, "--exposure", 2,
            "--tonemap", "aces", "--quiet", "-o", tmp_path / "cli.png")
    assert r.returncode == 0, r.stderr
    img = trayecto.render(trayecto.load_file("cornell"), width=16, height=16, spp=2,
                          exposure=2, tonemap="aces")
    assert img._repr_png_() == (tmp_path / "cli.png").read_bytes()


TOML = """
name = "dict scene"
[[camera]]
eye = [0.0, 1.0, 4.0]
target = [0.0, 0.5, 0.0]
fov = 45.0

[[material]]
name = "red"
base_color = [0.8, 0.1, 0.1]
roughness = 0.4

[[material]]
name = "lamp"
emissive = [4.0, 4.0, 3.0]

[[object]]
type = "sphere"
center = [0.0, 0.5, 0.0]
radius = 0.5
material = "red"

[[object]]
type = "box"
min = [-2.0, -0.1, -2.0]
max = [2.0, 0.0, 2.0]

[[object]]
type = "quad"
corner = [-0.5, 2.0, -0.5]
e1 = [1.0, 0.0, 0.0]
e2 = [0.0, 0.0, 1.0]
material = "lamp"

[[object]]
type = "mesh"
name = "tri"
positions = [[1.0, 0.0, 0.0], [1.8, 0.0, 0.0], [1.4, 1.0, 0.0]]
indices = [[0, 1, 2]]
normals = [[0.0, 0.0, 1.0], [0.0, 0.0, 1.0], [0.0, 0.0, 1.0]]
material = "red"

[[object]]
type = "mesh"
file = "cube.ply"
translate = [-1.2, 0.3, 0.0]
scale = 0.3

[[light]]
type = "point"
position = [2.0, 3.0, 2.0]
intensity = 5.0
"""

DICT = {
    "name": "dict scene",
    "camera": [{"eye": [0, 1, 4], "target": [0, 0.5, 0], "fov": 45}],
    "material": [
        {"name": "red", "base_color": (0.8, 0.1, 0.1), "roughness": 0.4},
        {"name": "lamp", "emissive": [4, 4, 3]},
    ],
    "object": [
        {"type": "sphere", "center": [0, 0.5, 0], "radius": 0.5, "material": "red"},
        {"type": "box", "min": [-2, -0.1, -2], "max": [2, 0, 2]},
        {"type": "quad", "corner": [-0.5, 2, -0.5], "e1": [1, 0, 0], "e2": [0, 0, 1],
         "material": "lamp"},
        {"type": "mesh", "name": "tri",
         "positions": np.array([[1, 0, 0], [1.8, 0, 0], [1.4, 1, 0]], dtype=np.float32),
         "indices": np.array([0, 1, 2], dtype=np.uint32),
         "normals": np.tile(np.float32([0, 0, 1]), 3), "material": "red"},
        {"type": "mesh", "file": "cube.ply", "translate": [-1.2, 0.3, 0], "scale": 0.3},
    ],
    "light": [{"type": "point", "position": [2, 3, 2], "intensity": 5}],
}


def test_load_dict_is_the_toml_scene(tmp_path):
    toml = tmp_path / "scene.toml"
    toml.write_text(TOML)
    (tmp_path / "cube.ply").write_bytes((SCENES / "twin" / "cube.ply").read_bytes())
    from_toml = trayecto.render(trayecto.load_file(toml), width=32, height=32, spp=4)
    from_dict = trayecto.render(trayecto.load_dict(DICT, base_dir=tmp_path),
                                width=32, height=32, spp=4)
    assert np.array_equal(from_toml.numpy(), from_dict.numpy())
    assert from_dict.numpy().max() > 0
    # The dict written out is a TOML scene file the command line renders the same.
    (tmp_path / "written.toml").write_text(trayecto.to_toml(DICT))
    r = cli("render", tmp_path / "written.toml", "--width", 32, "--height", 32, "--spp", 4,
            "--quiet", "-o", tmp_path / "cli.exr")
    assert r.returncode == 0, r.stderr
    from_dict.write(tmp_path / "py.exr")
    assert (tmp_path / "py.exr").read_bytes() == (tmp_path / "cli.exr").read_bytes()


def test_load_dict_errors():
    with pytest.raises(trayecto.SceneError, match="unknown type 'cone'"):
        trayecto.load_dict({"object": [{"type": "cone"}]})
    with pytest.raises(trayecto.SceneError, match="index 5 names no vertex"):
        trayecto.load_dict({"object": [{"type": "mesh", "positions": np.zeros((3, 3)),
                                        "indices": [[0, 1, 5]]}]})


def test_aovs(tmp_path):
    scene = trayecto.load_file("cornell")
    img = trayecto.render(scene, width=20, height=16, spp=2,
                          aovs=["albedo", "normal", "depth", "samples"])
    assert sorted(img.aovs) == ["albedo", "depth", "normal", "samples"]
    assert img.aov("albedo").shape == (16, 20, 3)
    assert img.aov("normal").shape == (16, 20, 3)
    assert img.aov("depth").shape[:2] == (16, 20)
    assert (img.aov("samples") == 2).all()
    assert np.abs(img.aov("normal")).max() <= 1.0 + 1e-6
    depth = img.aov("depth")  # infinite where the ray left through the open front
    assert np.isfinite(depth).any() and (depth[np.isfinite(depth)] > 0).all()
    with pytest.raises(KeyError):
        img.aov("variance")
    # The image is the same as without AOVs, and the CLI writes the same multi-layer EXR.
    plain = trayecto.render(scene, width=20, height=16, spp=2)
    assert np.array_equal(plain.numpy(), img.numpy())
    img.write(tmp_path / "py.exr")
    r = cli("render", "cornell", "--width", 20, "--height", 16, "--spp", 2,
            "--aov", "albedo,normal,depth,samples", "--quiet", "-o", tmp_path / "cli.exr")
    assert r.returncode == 0, r.stderr
    assert (tmp_path / "py.exr").read_bytes() == (tmp_path / "cli.exr").read_bytes()
    img.write(tmp_path / "py.png")
    assert (tmp_path / "py.albedo.png").is_file()


def test_numpy_shares_the_image_memory():
    img = trayecto.render(trayecto.load_file("cornell"), **TINY)
    a, b = img.numpy(), img.numpy()
    assert np.shares_memory(a, b)
    assert not a.flags.writeable
    del img  # the arrays keep the image alive
    assert np.isfinite(a).all() and a.sum() == b.sum()


def test_setting_errors():
    scene = trayecto.load_file("cornell")
    with pytest.raises(ValueError, match="sampler"):
        trayecto.render(scene, sampler="bogus", **TINY)
    with pytest.raises(TypeError, match="max_dpeth"):
        trayecto.render(scene, max_dpeth=3, **TINY)
    with pytest.raises(ValueError, match="filter_sigma"):
        trayecto.render(scene, filter="box", filter_sigma=1.0, **TINY)
    with pytest.raises(trayecto.SceneError, match="no camera 'nope'"):
        trayecto.render(scene, camera="nope", **TINY)
    with pytest.raises(ValueError):
        scene.set_material(0, roughness=float("nan"))
    with pytest.raises(KeyError):
        scene.set_material("no such material", roughness=0.5)
    with pytest.raises(ValueError, match="camera"):
        scene.camera = trayecto.Camera(eye=(0, 0, 0), target=(0, 0, 0))


def test_defaults_are_the_clis():
    d = trayecto.defaults()
    assert d["seed"] == 0 and d["spp"] is None and d["integrator"] is None
    assert d["sampler"] == "stratified" and d["rr_depth"] == 3 and d["secondary"] == 1
    img = trayecto.render(trayecto.load_file("cornell"), width=16, height=16)
    assert img.stats["samples_done"] == 64


def test_progress_callback_and_cancel():
    scene = trayecto.load_file("cornell")
    seen = []

    def progress(done, total):
        seen.append((done, total))
        return done == 0  # cancel once a tile is done

    t = time.monotonic()
    with pytest.raises(trayecto.Cancelled):
        trayecto.render(scene, width=256, height=256, spp=4096, progress=progress)
    assert time.monotonic() - t < 20
    assert seen and seen[-1][1] > 0
    # The scene renders again after a cancelled render.
    assert trayecto.render(scene, **TINY).numpy().max() > 0


def test_ctrl_c_cancels_cleanly():
    scene = trayecto.load_file("cornell")
    timer = threading.Timer(0.5, _thread.interrupt_main)
    timer.start()
    t = time.monotonic()
    with pytest.raises(KeyboardInterrupt):
        trayecto.render(scene, width=256, height=256, spp=4096)
    assert time.monotonic() - t < 20
    assert trayecto.render(scene, **TINY).numpy().max() > 0


def test_gil_released_while_rendering():
    scene = trayecto.load_file("cornell")
    ticks = []
    stop = threading.Event()

    def tick():
        while not stop.is_set():
            ticks.append(1)
            time.sleep(0.001)

    th = threading.Thread(target=tick)
    th.start()
    trayecto.render(scene, width=96, height=96, spp=64)
    stop.set()
    th.join()
    assert len(ticks) > 5


def test_camera_and_material_changes_without_reload():
    view = trayecto.Camera(eye=(278, 273, -600), target=(278, 273, 0), fov=45)
    scene = trayecto.load_file("cornell")
    before = trayecto.render(scene, **TINY).numpy().copy()
    scene.camera = view
    red = next(m for m in scene.materials if scene.material(m)["emissive"] == [0, 0, 0])
    scene.set_material(red, base_color=(0.2, 0.7, 0.3), roughness=0.3)
    after = trayecto.render(scene, **TINY).numpy()
    assert scene.builds == 1  # changed in place, not rebuilt
    assert not np.array_equal(before, after)
    assert scene.material(red)["roughness"] == pytest.approx(0.3)
    # The same changes made before the first render: the same image.
    fresh = trayecto.load_file("cornell")
    fresh.camera = view
    fresh.set_material(red, base_color=(0.2, 0.7, 0.3), roughness=0.3)
    assert np.array_equal(trayecto.render(fresh, **TINY).numpy(), after)
    # Back to the scene's own camera.
    scene.camera = None
    scene.set_material(red, base_color=trayecto.load_file("cornell").material(red)["base_color"],
                       roughness=trayecto.load_file("cornell").material(red)["roughness"])
    assert np.array_equal(trayecto.render(scene, **TINY).numpy(), before)


def test_light_intensity_rerendered(tmp_path):
    d = {
        "camera": [{"eye": [0, 1, 4], "target": [0, 0, 0]}],
        "object": [{"type": "box", "min": [-2, -0.1, -2], "max": [2, 0, 2]}],
        "light": [{"type": "point", "name": "key", "position": [0, 2, 0], "intensity": 3}],
        "default_light": "off",
    }
    scene = trayecto.load_dict(d)
    a = trayecto.render(scene, **TINY).numpy().copy()
    assert scene.lights[0]["intensity"] == [3, 3, 3]
    scene.set_light("key", 6)
    b = trayecto.render(scene, **TINY).numpy()
    assert np.allclose(b, 2 * a, rtol=1e-5)
    assert scene.builds == 2


def test_load_file_overrides():
    scene = trayecto.load_file("cornell", spp=3, width=8, height=8)
    img = trayecto.render(scene)
    assert (img.width, img.height, img.stats["samples_done"]) == (8, 8, 3)
    assert trayecto.render(scene, spp=1).stats["samples_done"] == 1
