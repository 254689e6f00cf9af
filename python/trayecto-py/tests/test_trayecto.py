"""Tests of the `trayecto` Python package against this checkout's command line (TRAYECTO_BIN):
every format loads, load_dict is the TOML scene, renders agree with the CLI bit for bit, AOVs,
errors, cancelling, and scenes changed and rendered again without reloading."""

import _thread
import os
import pathlib
import re
import subprocess
import threading
import time

import numpy as np
import pytest

import trayecto

ROOT = pathlib.Path(__file__).resolve().parents[3]
SCENES = ROOT / "scenes"
# The shared test data CI keeps beside the checkout (FBX files, animated glTF, Mitsuba scenes).
SHARED = ROOT.parent / "shared" / "scenes"
BIN = os.environ.get("TRAYECTO_BIN", str(ROOT / "target" / "debug" / "trayecto"))
TINY = dict(width=24, height=24, spp=2)


def shared(rel):
    path = SHARED / rel
    if not path.exists():
        pytest.skip(f"{path} is missing: the shared test data is not beside this checkout "
                    "(CI has it)")
    return path


def cli(*args):
    return subprocess.run([BIN, *map(str, args)], capture_output=True, text=True)


OBJ = """v -1 0 -1
v 1 0 -1
v 0 1.5 -1
vn 0 0 1
f 1//1 2//1 3//1
"""


MITSUBA = """<scene version="3.0.0">
    <default name="radius" value="0.5"/>
    <sensor type="perspective">
        <float name="fov" value="40"/>
        <transform name="to_world"><lookat origin="0, 1, 4" target="0, 0.4, 0" up="0, 1, 0"/></transform>
    </sensor>
    <shape type="sphere">
        <point name="center" x="0" y="0.5" z="0"/>
        <float name="radius" value="$radius"/>
        <bsdf type="diffuse"><rgb name="reflectance" value="0.7, 0.3, 0.2"/></bsdf>
    </shape>
    <emitter type="point"><point name="position" x="1" y="3" z="2"/><rgb name="intensity" value="8"/></emitter>
    <emitter type="constant"><rgb name="radiance" value="0.2"/></emitter>
</scene>
"""


def scene_file(name, tmp_path):
    """A scene file by test name: written here (OBJ, Mitsuba XML) or from the repository and
    the shared data."""
    if name == "OBJ":
        path = tmp_path / "tri.obj"
        path.write_text(OBJ)
        return path
    if name == "XML":
        path = tmp_path / "sphere.xml"
        path.write_text(MITSUBA)
        return path
    if isinstance(name, pathlib.Path) and SHARED in name.parents:
        return shared(name.relative_to(SHARED))
    return name


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
        "XML",
        SHARED / "fbx" / "cornell_seed_conventions_lights.fbx",
        SHARED / "mitsuba" / "scenes" / "shape_sphere_light_analytic.xml",
    ],
    ids=lambda p: pathlib.Path(str(p)).name,
)
def test_each_format_is_the_clis_image(path, tmp_path):
    path = scene_file(path, tmp_path)
    scene = trayecto.load_file(path)
    img = trayecto.render(scene, **TINY)
    a = img.numpy()
    assert a.shape == (24, 24, 3) and a.dtype == np.float32
    assert np.isfinite(a).all() and a.max() > 0
    img.write(tmp_path / "py.exr")
    r = cli("render", path, "--width", 24, "--height", 24, "--spp", 2, "--quiet",
            "-o", tmp_path / "cli.exr")
    assert r.returncode == 0, r.stderr
    assert (tmp_path / "py.exr").read_bytes() == (tmp_path / "cli.exr").read_bytes()


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
        (
            ["--clamp-direct", "0.5", "--clamp-indirect", "0.2", "--threads", "0"],
            dict(clamp_direct=0.5, clamp_indirect=0.2, threads=0),
        ),
        (["--guiding"], dict(guiding=True)),
        (["--transparent", "--sampler", "poisson-disk"],
         dict(transparent=True, sampler="poisson-disk")),
        (["--time-limit", "30"], dict(time_limit=30)),
    ],
)
def test_cornell_is_the_clis_image(flags, kw, tmp_path):
    size = ["--width", 40, "--height", 32, "--spp", 4]
    r = cli("render", "cornell", *size, *flags, "--quiet", "-o", tmp_path / "cli.exr")
    assert r.returncode == 0, r.stderr
    kw = dict(dict(width=40, height=32, spp=4), **kw)
    img = trayecto.render(trayecto.load_file("cornell"), **kw)
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


LIT = {
    "camera": [{"eye": [0, 1, 4], "target": [0, 0, 0]}],
    "object": [
        {"type": "box", "min": [-2, -0.1, -2], "max": [2, 0, 2]},
        {"type": "sphere", "center": [0.5, 0.4, 0], "radius": 0.4},
    ],
    "light": [
        {"type": "point", "name": "key", "position": [0, 2, 0], "intensity": 3},
        {"type": "spot", "name": "rim", "position": [-2, 2, 1], "direction": [1, -1, -0.5],
         "intensity": 2},
        {"type": "directional", "name": "sun", "direction": [0.3, -1, 0.2], "intensity": 0.5},
    ],
    "default_light": "off",
}


@pytest.mark.parametrize("light_sampler", ["power", "bvh"])
def test_light_changes_in_place(light_sampler):
    kw = dict(TINY, light_sampler=light_sampler)
    scene = trayecto.load_dict(LIT)
    a = trayecto.render(scene, **kw).numpy().copy()
    assert scene.lights[0]["intensity"] == [3, 3, 3]
    scene.set_light("key", 6)
    scene.set_light("rim", color=(1, 0.5, 0.25))
    scene.set_light(2, 0.25, color=(0.2, 0.4, 1))
    b = trayecto.render(scene, **kw).numpy()
    # Changed in the compiled world: neither loaded nor built again (no new BVH).
    assert scene.builds == 1
    assert scene.lights[1]["intensity"] == [2, 1, 0.5]
    assert scene.lights[2]["intensity"] == pytest.approx([0.05, 0.1, 0.25])
    assert not np.array_equal(a, b)
    # The image is the one of the scene built with those lights.
    fresh = trayecto.load_dict(LIT)
    fresh.set_light("key", 6)
    fresh.set_light("rim", color=(1, 0.5, 0.25))
    fresh.set_light("sun", 0.25, color=(0.2, 0.4, 1))
    assert np.array_equal(trayecto.render(fresh, **kw).numpy(), b)
    with pytest.raises(KeyError):
        scene.set_light("nope", 1)
    with pytest.raises(TypeError):
        scene.set_light("key", (1, 1, 1), color=(1, 0, 0))


def test_ambient_light_changes_in_place():
    d = dict(LIT, light=[{"type": "ambient", "name": "sky", "intensity": 0.5}])
    scene = trayecto.load_dict(d)
    a = trayecto.render(scene, **TINY).numpy().copy()
    scene.set_light("sky", 1.0)
    b = trayecto.render(scene, **TINY).numpy()
    assert scene.builds == 1
    assert np.allclose(b, 2 * a, rtol=1e-5)


def test_load_file_overrides():
    scene = trayecto.load_file("cornell", spp=3, width=8, height=8)
    img = trayecto.render(scene)
    assert (img.width, img.height, img.stats["samples_done"]) == (8, 8, 3)
    assert trayecto.render(scene, spp=1).stats["samples_done"] == 1


# Command-line options the Python API has no render keyword for, and why.
CLI_ONLY = {
    "help": "prints the help",
    "output": "Image.write(path) writes the image (by extension, AOVs and .trp as -o does)",
    "quiet": "nothing is printed: warnings are Scene.warnings",
    "frames": "writes numbered files: a loop over frame= gives one Image per frame",
}
# The API names the AOV list `aovs`; the command line's option is --aov.
RENAMED = {"aov": "aovs"}


def cli_render_options():
    """The long options of `trayecto render --help` and their defaults (`[default: X]`)."""
    r = cli("render", "--help")
    assert r.returncode == 0, r.stderr
    options, current = {}, None
    for line in r.stdout.splitlines():
        m = re.match(r"^ {2,6}(?:-\w, )?--([a-z0-9-]+)", line)
        if m:
            current = m.group(1)
            options[current] = None
        elif re.match(r"^ {2,6}[\[<]", line):
            current = None  # a positional argument (the scene)
        d = re.search(r"\[default: ([^\]]*)\]", line)
        if d and current:
            options[current] = d.group(1)
    assert len(options) > 40, r.stdout
    return options


def test_every_cli_render_option_is_a_keyword_with_its_default():
    options = cli_render_options()
    keywords = trayecto.defaults()
    missing = [o for o in options if o not in CLI_ONLY
               and RENAMED.get(o, o).replace("-", "_") not in keywords]
    assert not missing, f"CLI render options without a keyword: {missing}"
    stale = [o for o in CLI_ONLY if o not in options]
    assert not stale, f"CLI_ONLY names options the CLI no longer has: {stale}"
    names = {RENAMED.get(o, o).replace("-", "_") for o in options}
    assert not set(keywords) - names, "keywords the command line does not have"
    for o, default in options.items():
        if default is None or o in CLI_ONLY:
            continue
        mine = keywords[o.replace("-", "_")]
        if isinstance(mine, (int, float)) and not isinstance(mine, bool):
            assert float(default) == mine, o
        else:
            assert default == mine, o


def test_choices_round_trip_as_the_cli_spells_them(tmp_path):
    scene = trayecto.load_file("cornell")
    for option, names in trayecto.choices().items():
        assert trayecto.defaults()[option] in names
        for name in names:
            extra = dict(integrator="whitted") if option == "shading" else {}
            img = trayecto.render(scene, width=8, height=8, spp=1, **{option: name}, **extra)
            assert img.settings[option] == name
            img.write(tmp_path / "py.exr")
            flags = ["--integrator", "whitted"] if extra else []
            r = cli("render", "cornell", "--width", 8, "--height", 8, "--spp", 1, *flags,
                    f"--{option.replace('_', '-')}", name, "--quiet", "-o", tmp_path / "cli.exr")
            assert r.returncode == 0, (option, name, r.stderr)
            assert (tmp_path / "py.exr").read_bytes() == (tmp_path / "cli.exr").read_bytes()


def test_every_integrator_the_cli_names_is_the_clis_image(tmp_path):
    r = cli("render", "cornell", "--integrator", "nope", "-o", tmp_path / "x.png")
    listed = re.search(r"expected ([^)]*)\)", r.stderr).group(1)
    names = re.split(r", | or ", listed)
    assert "path" in names and "bdpt" in names
    with pytest.raises(ValueError, match=re.escape(listed)):
        trayecto.render(trayecto.load_file("cornell"), integrator="nope", **TINY)
    scene = trayecto.load_file("cornell")
    for name in names:
        img = trayecto.render(scene, integrator=name, width=16, height=16, spp=2)
        assert img.settings["integrator"] == name
        img.write(tmp_path / "py.exr")
        r = cli("render", "cornell", "--integrator", name, "--width", 16, "--height", 16,
                "--spp", 2, "--quiet", "-o", tmp_path / "cli.exr")
        assert r.returncode == 0, r.stderr
        assert (tmp_path / "py.exr").read_bytes() == (tmp_path / "cli.exr").read_bytes(), name


SIZE = dict(width=24, height=16, spp=4)
SIZE_FLAGS = ["--width", 24, "--height", 16, "--spp", 4]


def test_sample_ranges_merge_into_the_clis_image(tmp_path):
    scene = trayecto.load_file("cornell")
    first = trayecto.render(scene, samples="0..2", **SIZE)
    first.write(tmp_path / "a.trp")
    second = trayecto.render(scene, samples=(2, 4), **SIZE)
    second.write(tmp_path / "b.trp")
    with pytest.raises(ValueError, match="partial film"):
        first.write(tmp_path / "a.png")
    with pytest.raises(ValueError, match="samples="):
        trayecto.render(scene, **SIZE).write(tmp_path / "whole.trp")
    # A part from here and one from the command line merge: the same frame.
    r = cli("render", "cornell", *SIZE_FLAGS, "--samples", "2..4", "--quiet",
            "-o", tmp_path / "cli_b.trp")
    assert r.returncode == 0, r.stderr
    for b in ("b.trp", "cli_b.trp"):
        r = cli("merge", tmp_path / "a.trp", tmp_path / b, "--quiet", "-o", tmp_path / "m.exr")
        assert r.returncode == 0, r.stderr
        trayecto.render(scene, **SIZE).write(tmp_path / "whole.exr")
        assert (tmp_path / "m.exr").read_bytes() == (tmp_path / "whole.exr").read_bytes()
    with pytest.raises(ValueError, match="sample range"):
        trayecto.render(scene, samples="3..9", **SIZE)


def test_checkpoint_and_resume(tmp_path):
    scene = trayecto.load_file("cornell")
    ck = tmp_path / "ck.trp"
    whole = trayecto.render(scene, checkpoint=ck, checkpoint_interval=0, **SIZE)
    assert ck.is_file()
    resumed = trayecto.render(scene, resume=ck, **SIZE)
    assert np.array_equal(resumed.numpy(), whole.numpy())
    # The command line resumes the checkpoint written here to the same image.
    whole.write(tmp_path / "py.exr")
    r = cli("render", "cornell", *SIZE_FLAGS, "--resume", ck, "--quiet", "-o", tmp_path / "cli.exr")
    assert r.returncode == 0, r.stderr
    assert (tmp_path / "py.exr").read_bytes() == (tmp_path / "cli.exr").read_bytes()
    with pytest.raises(ValueError, match="no such checkpoint"):
        trayecto.render(scene, resume=tmp_path / "none.trp", **SIZE)


def test_denoise_as_the_cli(tmp_path):
    scene = trayecto.load_file("cornell")
    with pytest.raises(ValueError, match="denoise"):
        trayecto.render(scene, oidn="/nowhere/libOpenImageDenoise.so", **SIZE)
    r = cli("render", "cornell", *SIZE_FLAGS, "--denoise", "--quiet", "-o", tmp_path / "cli.exr")
    if r.returncode != 0:
        # No Open Image Denoise here: the same error as the command line's.
        with pytest.raises(trayecto.RenderError) as e:
            trayecto.render(scene, denoise=True, **SIZE)
        assert r.stderr.strip() == f"error: {e.value}"
        return
    img = trayecto.render(scene, denoise=True, **SIZE)
    assert img.denoised().shape == img.numpy().shape
    img.write(tmp_path / "py.exr")
    for f in ("exr", "denoised.exr"):
        assert (tmp_path / f"py.{f}").read_bytes() == (tmp_path / f"cli.{f}").read_bytes()


def test_loading_keywords_are_the_clis(tmp_path):
    # define: a Mitsuba parameter, as -D.
    xml = scene_file("XML", tmp_path)
    big = trayecto.render(trayecto.load_file(xml, define={"radius": 0.8}), **TINY)
    small = trayecto.render(trayecto.load_file(xml), **TINY)
    assert not np.array_equal(big.numpy(), small.numpy())
    big.write(tmp_path / "py.exr")
    r = cli("render", xml, "-D", "radius=0.8", "--width", 24, "--height", 24, "--spp", 2,
            "--quiet", "-o", tmp_path / "cli.exr")
    assert r.returncode == 0, r.stderr
    assert (tmp_path / "py.exr").read_bytes() == (tmp_path / "cli.exr").read_bytes()
    same = trayecto.render(trayecto.load_file(xml, define=["radius=0.8"]), **TINY)
    assert np.array_equal(same.numpy(), big.numpy())
    with pytest.raises(ValueError, match="load_file"):
        trayecto.render(trayecto.load_file(xml), define={"radius": 1}, **TINY)
    # memory_limit and confine_paths: the command line's errors.
    glb = SCENES / "gltf-files" / "spheres_quantized.glb"
    with pytest.raises(trayecto.SceneError) as e:
        trayecto.load_file(glb, memory_limit="1M")
    assert trayecto.load_file(glb, memory_limit=64 << 20).name is not None
    r = cli("render", glb, "--memory-limit", "1M", "-o", tmp_path / "x.png")
    assert r.returncode != 0 and r.stderr.strip() == f"error: {e.value}"
    (tmp_path / "sub").mkdir()
    (tmp_path / "cube.ply").write_bytes((SCENES / "twin" / "cube.ply").read_bytes())
    toml = tmp_path / "sub" / "s.toml"
    toml.write_text('[[object]]\ntype = "mesh"\nfile = "../cube.ply"\n')
    assert trayecto.load_file(toml).name is not None
    with pytest.raises(trayecto.SceneError) as e:
        trayecto.load_file(toml, confine_paths=True)
    r = cli("render", toml, "--confine-paths", "-o", tmp_path / "x.png")
    assert r.returncode != 0 and r.stderr.strip() == f"error: {e.value}"


def test_animation_keywords_are_the_clis(tmp_path):
    glb = shared("gltf-anim/BoxAnimated/glTF-Binary/BoxAnimated.glb")
    scene = trayecto.load_file(glb)
    cases = [
        (["--time", "1.5"], dict(time=1.5)),
        (["--frame", "12", "--fps", "10"], dict(frame=12, fps=10)),
        (["--time", "1", "--shutter", "0,0.5", "--shutter-steps", "3"],
         dict(time=1, shutter=(0, 0.5), shutter_steps=3)),
    ]
    images = []
    for flags, kw in cases:
        img = trayecto.render(scene, **TINY, **kw)
        img.write(tmp_path / "py.exr")
        r = cli("render", glb, "--width", 24, "--height", 24, "--spp", 2, *flags, "--quiet",
                "-o", tmp_path / "cli.exr")
        assert r.returncode == 0, r.stderr
        assert (tmp_path / "py.exr").read_bytes() == (tmp_path / "cli.exr").read_bytes(), flags
        images.append(img.numpy())
    assert not np.array_equal(images[0], images[1])


def test_type_stubs_name_every_keyword():
    stubs = (pathlib.Path(trayecto.__file__).parent / "__init__.pyi").read_text()
    render = stubs[stubs.index("def render("):]
    render = render[:render.index(") -> Image:")]
    typed = set(re.findall(r"^\s+(\w+):", render, re.M))
    assert set(trayecto.defaults()) <= typed, set(trayecto.defaults()) - typed
    assert typed - {"scene", "progress"} <= set(trayecto.defaults())


def test_pbrt_files_render_spectrally_unless_told(tmp_path):
    # As `trayecto render FILE.pbrt`: spectral by default (pbrt-v4 renders every file so), RGB
    # with rgb=True or spectral=False, RGB for an integrator without a spectral path; other
    # formats RGB unless spectral=True. The same bytes as the command line's.
    scene = trayecto.load_file(str(SCENES / "pbrt" / "metals.pbrt"))
    small = dict(width=16, height=4, spp=2)
    img = trayecto.render(scene, **small)
    assert img.settings["spectral"] is True
    img.write(tmp_path / "py.exr")
    r = cli("render", SCENES / "pbrt" / "metals.pbrt", "--width", 16, "--height", 4, "--spp", 2,
            "--quiet", "-o", tmp_path / "cli.exr")
    assert r.returncode == 0, r.stderr
    assert (tmp_path / "py.exr").read_bytes() == (tmp_path / "cli.exr").read_bytes()
    assert trayecto.render(scene, rgb=True, **small).settings["spectral"] is False
    assert trayecto.render(scene, spectral=False, **small).settings["spectral"] is False
    assert trayecto.render(scene, integrator="whitted", **small).settings["spectral"] is False
    with pytest.raises(ValueError, match="not both"):
        trayecto.render(scene, spectral=True, rgb=True, **small)
    with pytest.raises(Exception, match="spectral rendering is not available"):
        trayecto.render(scene, spectral=True, integrator="whitted", **small)
    cornell = trayecto.load_file("cornell")
    assert trayecto.render(cornell, **TINY).settings["spectral"] is False
    assert trayecto.render(cornell, spectral=True, **TINY).settings["spectral"] is True
