"""Trayecto, a physically based path tracer, from Python.

    >>> import trayecto
    >>> scene = trayecto.load_file("cornell")          # a file, or a built-in scene
    >>> img = trayecto.render(scene, spp=16, width=128, height=128)
    >>> img.numpy().shape                               # float32, linear RGB, no copy
    (128, 128, 3)
    >>> scene.set_material(scene.materials[0], roughness=0.2)
    >>> img2 = trayecto.render(scene, spp=16, width=128, height=128)   # no reload

`render` takes every render option of the command line (``trayecto render --help``) as a keyword
of the same name (dashes as underscores) and default: ``trayecto.defaults()`` lists them.
"""

import inspect
import os
from collections import namedtuple

# numpy is what images are read as: imported with the package, so that the first
# `Image.numpy()` does not pay for it.
import numpy as _numpy  # noqa: F401

from . import _trayecto
from ._trayecto import (
    RENDER_IDENTITY,
    Cancelled,
    Image,
    RenderError,
    Scene,
    SceneError,
    builtin_scenes,
    choices,
)

__all__ = [
    "Camera",
    "Cancelled",
    "Image",
    "RenderError",
    "Scene",
    "SceneError",
    "builtin_scenes",
    "choices",
    "defaults",
    "load_dict",
    "load_file",
    "render",
    "to_toml",
    "RENDER_IDENTITY",
]

Camera = namedtuple("Camera", ["eye", "target", "up", "fov"], defaults=[(0.0, 1.0, 0.0), 39.6])
Camera.__doc__ = """A view for ``scene.camera``: eye and target points, up vector, vertical
field of view in degrees (default 39.6, the TOML scene's)."""


def defaults():
    """Every keyword of `render` and its default (the command line's): ``None`` means the scene
    file's own setting where it has one (size, samples, depth, filter), else the built-in one."""
    return dict(_trayecto.defaults())


_DEFAULTS = _trayecto.defaults()

# The keywords read while the scene is loaded (the command line's --memory-limit,
# --confine-paths and -D): `load_file` and `load_dict` take them.
_LOAD_KEYS = ("memory_limit", "confine_paths", "define")


def _split_load(overrides, fn):
    _check_keywords(overrides, fn)
    load = {k: overrides.pop(k) for k in _LOAD_KEYS if k in overrides}
    return load


def load_file(path, **overrides):
    """Loads a scene file (.gltf, .glb, .obj, .ply, .fbx, .pbrt, .xml, .toml, ...) or a built-in
    scene by name (``builtin_scenes()``). Errors raise `SceneError` with the command line's
    message.

    The loading keywords are the command line's: ``memory_limit`` (bytes or ``"4G"``),
    ``confine_paths`` and ``define`` (Mitsuba parameters, ``{"spp": 16}`` or
    ``["spp=16"]``, the command line's ``-D``). Other ``overrides`` are render keywords (e.g.
    ``camera=1``, ``variant="red"``, ``spp=16``) kept with the scene: every `render` of it uses
    them unless the call gives its own."""
    load = _split_load(overrides, "load_file")
    scene = _trayecto.load_file(os.fspath(path), _paths(load))
    scene._overrides = dict(overrides)
    scene._load = load
    return scene


def _paths(d):
    return {k: (os.fspath(v) if isinstance(v, os.PathLike) else v) for k, v in d.items()}


def _check_keywords(kw, fn):
    for k in kw:
        if k not in _DEFAULTS:
            raise TypeError(f"{fn}() got an unexpected keyword argument '{k}'")


def _mesh_arrays(d):
    """Inline meshes given as numpy arrays of any shape (N,3), (3N,) become lists of triples."""
    if isinstance(d, dict):
        out = {}
        for k, v in d.items():
            if k in ("positions", "normals", "indices", "uvs") and hasattr(v, "reshape"):
                width = 2 if k == "uvs" else 3
                v = v.reshape(-1, width).tolist()
            out[k] = _mesh_arrays(v)
        return out
    if isinstance(d, (list, tuple)):
        return [_mesh_arrays(x) for x in d]
    return d


def to_toml(d):
    """The TOML scene file a `load_dict` dict is: ``open("scene.toml", "w").write(to_toml(d))``
    gives the same scene."""
    return _trayecto.to_toml_text(_mesh_arrays(d))


def load_dict(d, base_dir=None, **overrides):
    """A scene from plain dicts and lists with the native TOML scene's schema (``[[object]]`` is
    ``"object": [{...}, ...]``, see scenes/example.toml): cameras, materials, objects (mesh files,
    inline meshes as numpy arrays ``positions``/``indices``/``normals``/``uvs``, spheres, boxes,
    quads), lights, media. Files it names are read relative to ``base_dir`` (default: the current
    folder). ``overrides`` as for `load_file`."""
    load = _split_load(overrides, "load_dict")
    scene = _trayecto.load_dict(_mesh_arrays(d), os.fspath(base_dir or os.getcwd()), load)
    scene._overrides = dict(overrides)
    scene._load = load
    return scene


def _progress_callback(progress):
    if progress is None or progress is False:
        return None, None
    if callable(progress) and progress is not True:
        return progress, None
    try:
        from tqdm.auto import tqdm
    except ImportError:  # no tqdm: no bar
        return None, None
    bar = tqdm(total=1, unit="tile", leave=False)

    def update(done, total):
        if total and bar.total != total:
            bar.total = total
        bar.update(done - bar.n)

    return update, bar


def render(scene, *, aovs=(), progress=None, **settings):
    options = dict(getattr(scene, "_overrides", {}))
    options.update(settings)
    _check_keywords(options, "render")
    loaded = getattr(scene, "_load", {})
    for k in _LOAD_KEYS:
        if k in options and options.pop(k) != loaded.get(k, _DEFAULTS[k]):
            raise ValueError(
                f"{k} is read while the scene is loaded: give it to load_file() or load_dict()"
            )
    options["aovs"] = [aovs] if isinstance(aovs, str) else list(aovs)
    options = _paths(options)
    callback, bar = _progress_callback(progress)
    try:
        return _trayecto.render(scene, options, callback)
    finally:
        if bar is not None:
            bar.close()


def _signature():
    params = [inspect.Parameter("scene", inspect.Parameter.POSITIONAL_OR_KEYWORD)]
    for name, default in _DEFAULTS.items():
        params.append(inspect.Parameter(name, inspect.Parameter.KEYWORD_ONLY, default=default))
    params.append(inspect.Parameter("progress", inspect.Parameter.KEYWORD_ONLY, default=None))
    return inspect.Signature(params)


render.__signature__ = _signature()
render.__doc__ = """Renders `scene` and returns an `Image` (``.numpy()``, ``.aov(name)``,
``.write(path)``).

Every render option of the command line is a keyword with the same name (dashes as underscores)
and the same default (``trayecto.defaults()``): ``spp``, ``seed``, ``width``, ``height``,
``integrator``, ``threads``, ``max_depth``, ``sampler``, ``filter``, ``camera``, ... ``width``,
``height``, ``spp`` and ``max_depth`` default to the scene file's own settings, else 512x512 (or
the camera's aspect ratio), 64 spp and depth 64, as on the command line. ``aovs`` (the command
line's ``--aov``) lists AOV layers (albedo, normal, depth, position, shading_normal,
material_id, object_id, samples, variance, alpha). ``exposure`` and ``tonemap`` are kept for
``Image.write`` and the notebook display. Named values are spelled as on the command line
(``trayecto.choices()``).

Splitting and resuming: ``samples="0..16"`` (or ``(0, 16)``) renders a sample range of the
frame, written with ``Image.write("part.trp")`` and merged with ``trayecto merge``;
``checkpoint=FILE`` saves the film during the render and when it is cancelled,
``resume=FILE`` continues it. ``denoise=True`` also denoises with Open Image Denoise
(``Image.denoised()``; ``write`` writes ``out.denoised.png`` beside ``out.png``). ``time``,
``frame``, ``fps``, ``shutter`` and ``shutter_steps`` pose an animated scene and blur its
motion. ``memory_limit``, ``confine_paths`` and ``define`` are read while loading: give them
to `load_file`.

``progress``: a callable ``progress(done, total)`` (tiles; return ``False`` to cancel), or
``True`` for a tqdm bar when tqdm is installed. The GIL is released while rendering; Ctrl-C
cancels the render cleanly (``KeyboardInterrupt``)."""
