"""Type stubs of the `trayecto` package (the docstrings are in the module itself)."""

import os
from typing import Any, Callable, Mapping, NamedTuple, Optional, Sequence, Tuple, Union

import numpy as np
import numpy.typing as npt

Vec3 = Union[float, Tuple[float, float, float], Sequence[float]]
PathLike = Union[str, "os.PathLike[str]"]

RENDER_IDENTITY: str

class SceneError(Exception): ...
class RenderError(Exception): ...
class Cancelled(Exception): ...

class Camera(NamedTuple):
    eye: Vec3
    target: Vec3
    up: Vec3 = (0.0, 1.0, 0.0)
    fov: float = 39.6

class Scene:
    @property
    def name(self) -> str: ...
    @property
    def warnings(self) -> list[str]: ...
    @property
    def cameras(self) -> list[str]: ...
    @property
    def materials(self) -> list[str]: ...
    @property
    def builds(self) -> int: ...
    @property
    def camera(self) -> Optional[dict[str, Any]]: ...
    @camera.setter
    def camera(self, view: Union[Camera, Mapping[str, Any], None]) -> None: ...
    def material(self, name: Union[str, int]) -> dict[str, Any]: ...
    def set_material(
        self,
        name: Union[str, int],
        *,
        base_color: Vec3 = ...,
        metallic: float = ...,
        roughness: float = ...,
        emissive: Vec3 = ...,
        transmission: float = ...,
        ior: float = ...,
        specular: float = ...,
        specular_color: Vec3 = ...,
        alpha: float = ...,
        normal_scale: float = ...,
        thin_walled: bool = ...,
        double_sided: bool = ...,
    ) -> None: ...
    @property
    def lights(self) -> list[dict[str, Any]]: ...
    def set_light(
        self,
        name: Union[str, int],
        intensity: Optional[Vec3] = None,
        color: Optional[Vec3] = None,
    ) -> None: ...

class Image:
    @property
    def width(self) -> int: ...
    @property
    def height(self) -> int: ...
    @property
    def aovs(self) -> list[str]: ...
    @property
    def stats(self) -> dict[str, Any]: ...
    @property
    def settings(self) -> dict[str, Any]: ...
    def numpy(self) -> npt.NDArray[np.float32]: ...
    def denoised(self) -> npt.NDArray[np.float32]: ...
    def aov(self, name: str) -> npt.NDArray[np.float32]: ...
    def write(
        self, path: PathLike, exposure: Optional[float] = None, tonemap: Optional[str] = None
    ) -> None: ...
    def _repr_png_(self) -> bytes: ...

Defines = Union[Mapping[str, Any], Sequence[str], str, None]

def builtin_scenes() -> list[str]: ...
def choices() -> dict[str, list[str]]: ...
def defaults() -> dict[str, Any]: ...
def load_file(
    path: PathLike,
    *,
    memory_limit: Union[int, str, None] = None,
    confine_paths: bool = False,
    define: Defines = None,
    **overrides: Any,
) -> Scene: ...
def load_dict(
    d: Mapping[str, Any],
    base_dir: Optional[PathLike] = None,
    *,
    memory_limit: Union[int, str, None] = None,
    confine_paths: bool = False,
    define: Defines = None,
    **overrides: Any,
) -> Scene: ...
def to_toml(d: Mapping[str, Any]) -> str: ...
def render(
    scene: Scene,
    *,
    spp: Optional[int] = ...,
    seed: int = ...,
    width: Optional[int] = ...,
    height: Optional[int] = ...,
    integrator: Optional[str] = ...,
    threads: Optional[int] = ...,
    aovs: Union[str, Sequence[str]] = ...,
    secondary: int = ...,
    max_depth: Optional[int] = ...,
    exposure: float = ...,
    tonemap: str = ...,
    shading: str = ...,
    accel: str = ...,
    sampler: str = ...,
    no_nee: bool = ...,
    no_mis: bool = ...,
    rr_depth: int = ...,
    rr_scale: float = ...,
    camera: Union[str, int, None] = ...,
    default_light: Optional[str] = ...,
    no_default_light: bool = ...,
    env: Optional[PathLike] = ...,
    env_rotation: Optional[float] = ...,
    camera_from: Optional[PathLike] = ...,
    variant: Optional[str] = ...,
    light_sampler: str = ...,
    texture_filter: str = ...,
    filter: Optional[str] = ...,
    filter_radius: Optional[float] = ...,
    filter_sigma: Optional[float] = ...,
    noise_threshold: Optional[float] = ...,
    time_limit: Optional[float] = ...,
    crop: Union[str, Sequence[float], None] = ...,
    pixel_bounds: Union[str, Sequence[int], None] = ...,
    guiding: Optional[bool] = ...,
    no_guiding: bool = ...,
    clamp_direct: Optional[float] = ...,
    clamp_indirect: Optional[float] = ...,
    photons_per_iteration: Optional[int] = ...,
    photon_radius: Optional[float] = ...,
    vcm_no_merge: bool = ...,
    mlt_bootstrap_samples: Optional[int] = ...,
    mlt_chains: Optional[int] = ...,
    mlt_large_step_probability: Optional[float] = ...,
    mlt_sigma: Optional[float] = ...,
    transparent: bool = ...,
    spectral: bool | None = ...,
    rgb: bool = ...,
    time: Optional[float] = ...,
    frame: Optional[int] = ...,
    fps: Optional[float] = ...,
    shutter: Union[str, Tuple[float, float], None] = ...,
    shutter_steps: Optional[int] = ...,
    samples: Union[str, Tuple[int, int], range, None] = ...,
    checkpoint: Optional[PathLike] = ...,
    checkpoint_interval: float = ...,
    resume: Optional[PathLike] = ...,
    denoise: bool = ...,
    oidn: Optional[PathLike] = ...,
    memory_limit: Union[int, str, None] = ...,
    confine_paths: bool = ...,
    define: Defines = ...,
    progress: Union[bool, Callable[[int, int], Optional[bool]], None] = ...,
) -> Image: ...
