"""Split Trayecto frames into sample-range chunks, render them as Dask tasks, merge them exactly.

Each task runs ``trayecto render SCENE --spp N --samples A..B -o part.trp`` on a worker and returns
the partial film's bytes; the driver writes the parts to a temporary folder and runs ``trayecto
merge``, which checks that they belong to one frame and cover every sample once. Trayecto's sums are
exact fixed-point integers, so the merged image is bit-identical to a single ``--spp N`` render,
whichever way the frame was split and whichever worker rendered which chunk.

A task whose worker dies is rescheduled by Dask on another worker (the scheduler notices the lost
worker and recomputes its tasks); a task that fails (the renderer exits non-zero) is retried
``retries`` times. Rendering a chunk twice is harmless: a chunk is a pure function of its inputs.
"""

from __future__ import annotations

import hashlib
import io
import os
import shutil
import subprocess
import tempfile
import zipfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Iterable, Optional, Sequence


class FarmError(RuntimeError):
    """A problem the user can fix (bad options, a renderer error), reported without a traceback."""


def plan_chunks(spp: int, chunks: int) -> list[tuple[int, int]]:
    """Splits sample indices ``0..spp`` into ``chunks`` contiguous ranges of (nearly) equal size."""
    if spp < 1:
        raise FarmError(f"--spp must be at least 1 (got {spp})")
    if chunks < 1:
        raise FarmError(f"--chunks must be at least 1 (got {chunks})")
    chunks = min(chunks, spp)
    bounds = [spp * i // chunks for i in range(chunks + 1)]
    return [(bounds[i], bounds[i + 1]) for i in range(chunks)]


@dataclass(frozen=True)
class Bundle:
    """A scene's folder packed as a zip, for workers that do not share the driver's filesystem.

    ``scene`` is the scene file's path inside the bundle. Workers unpack it once per content hash
    into their temporary folder.
    """

    digest: str
    data: bytes
    scene: str

    @staticmethod
    def of(scene: Path, root: Optional[Path] = None) -> "Bundle":
        scene = scene.resolve()
        root = (root or scene.parent).resolve()
        try:
            rel = scene.relative_to(root)
        except ValueError:
            raise FarmError(f"{scene} is not inside the bundle folder {root}") from None
        buf = io.BytesIO()
        with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as z:
            for p in sorted(root.rglob("*")):
                if p.is_file() and not p.is_symlink():
                    z.write(p, p.relative_to(root).as_posix())
        data = buf.getvalue()
        return Bundle(hashlib.sha256(data).hexdigest(), data, rel.as_posix())

    def unpack(self) -> Path:
        """Unpacks (once per worker machine and content) and returns the scene file's path."""
        dest = Path(tempfile.gettempdir()) / f"trayecto-bundle-{self.digest[:16]}"
        done = dest / ".complete"
        if not done.exists():
            tmp = Path(tempfile.mkdtemp(prefix="trayecto-bundle-"))
            with zipfile.ZipFile(io.BytesIO(self.data)) as z:
                for name in z.namelist():
                    # zipfile refuses absolute paths, but check '..' ourselves: never write
                    # outside the bundle folder.
                    target = (tmp / name).resolve()
                    if not str(target).startswith(str(tmp.resolve()) + os.sep):
                        raise FarmError(f"bundle entry {name!r} points outside the bundle")
                z.extractall(tmp)
            (tmp / ".complete").touch()
            try:
                tmp.rename(dest)
            except OSError:
                # Another task on this machine unpacked it first.
                shutil.rmtree(tmp, ignore_errors=True)
        return dest / self.scene


@dataclass(frozen=True)
class Task:
    """One chunk of one frame."""

    frame: int
    scene: str
    camera: Optional[str]
    samples: tuple[int, int]
    # The animation frame rendered (``trayecto render --frame N``), if any.
    anim_frame: Optional[int] = None


def render_chunk(
    trayecto: str,
    task: Task,
    spp: int,
    render_args: Sequence[str],
    threads: Optional[int],
    bundle: Optional[Bundle] = None,
) -> bytes:
    """Runs on a worker: renders one chunk and returns the partial film's bytes."""
    scene = str(bundle.unpack()) if bundle is not None else task.scene
    with tempfile.TemporaryDirectory(prefix="trayecto-chunk-") as d:
        out = Path(d) / "part.trp"
        cmd = [
            trayecto,
            "render",
            scene,
            "--spp",
            str(spp),
            "--samples",
            f"{task.samples[0]}..{task.samples[1]}",
            "-o",
            str(out),
            "--quiet",
            *render_args,
        ]
        if task.camera is not None:
            cmd += ["--camera", task.camera]
        if task.anim_frame is not None:
            cmd += ["--frame", str(task.anim_frame)]
        if threads is not None:
            cmd += ["--threads", str(threads)]
        try:
            r = subprocess.run(cmd, capture_output=True, text=True)
        except FileNotFoundError:
            raise FarmError(
                f"the worker cannot run '{trayecto}': install Trayecto on every worker or pass "
                "--trayecto with its path there"
            ) from None
        if r.returncode != 0:
            raise FarmError(
                f"trayecto failed on {scene} samples {task.samples[0]}..{task.samples[1]} "
                f"(exit {r.returncode}): {r.stderr.strip()}"
            )
        return out.read_bytes()


@dataclass
class FarmJob:
    """What to render: frames (scene files × cameras), each split into ``chunks`` sample ranges."""

    scenes: list[str]
    spp: int
    chunks: int
    output: Path
    cameras: list[Optional[str]] = field(default_factory=lambda: [None])
    # Frames of an animation (``--frames A..B``): each is a frame of the job, split into chunks.
    anim_frames: list[Optional[int]] = field(default_factory=lambda: [None])
    render_args: list[str] = field(default_factory=list)
    trayecto: str = "trayecto"
    threads_per_task: Optional[int] = None
    bundle: bool = False
    bundle_root: Optional[Path] = None
    retries: int = 2

    def frames(self) -> list[tuple[str, Optional[str]]]:
        return [(s, c) for s in self.scenes for c in self.cameras for _ in self.anim_frames]

    def frame_output(self, i: int) -> Path:
        """``out.exr`` for one frame; ``out_0000.exr``, ``out_0001.exr``, … for several; frames of
        one animation are numbered by frame, as ``trayecto render --frames`` numbers them."""
        if len(self.frames()) == 1:
            return self.output
        if len(self.scenes) * len(self.cameras) == 1 and self.anim_frames[0] is not None:
            i = self.anim_frames[i]
        return self.output.with_name(f"{self.output.stem}_{i:04d}{self.output.suffix}")

    def tasks(self) -> list[Task]:
        ranges = plan_chunks(self.spp, self.chunks)
        n = len(self.anim_frames)
        return [
            Task(i, scene, cam, r, self.anim_frames[i % n])
            for i, (scene, cam) in enumerate(self.frames())
            for r in ranges
        ]


def _sppm_requested(args: list[str]) -> bool:
    """Whether the render options ask for ``--integrator sppm``."""
    return any(
        (a == "--integrator" and i + 1 < len(args) and args[i + 1] == "sppm")
        or a == "--integrator=sppm"
        for i, a in enumerate(args)
    )


def _check_local(job: FarmJob) -> None:
    # SPPM's pixels carry their photon radius from one iteration to the next, so its iterations
    # cannot be rendered apart (the renderer refuses a range not starting at 0); VCM's can.
    if job.chunks > 1 and job.spp > 1 and _sppm_requested(job.render_args):
        raise FarmError(
            "--integrator sppm cannot be split into chunks: each pixel's photon radius depends on "
            "every earlier iteration; use --chunks 1, or --integrator vcm (its iterations split)"
        )
    for s in job.scenes:
        p = Path(s)
        if (os.sep in s or p.suffix) and not p.is_file():
            raise FarmError(f"{s}: no such scene file")
    if job.output.parent != Path("") and not job.output.parent.is_dir():
        raise FarmError(f"{job.output}: the output folder does not exist")


def run_farm(
    job: FarmJob,
    client,
    merge_trayecto: Optional[str] = None,
    progress: Optional[Callable[[int, int], None]] = None,
) -> list[Path]:
    """Submits every chunk of every frame to ``client`` (a ``distributed.Client``), waits, and merges
    each frame with the local ``merge_trayecto`` (default: ``job.trayecto``). Returns the images.
    ``progress(done, total)`` is called as chunks finish."""
    from distributed import as_completed

    _check_local(job)
    tasks = job.tasks()
    bundles = {}
    if job.bundle:
        for s in job.scenes:
            b = Bundle.of(Path(s), job.bundle_root)
            # Sent to the cluster once, not once per task.
            bundles[s] = client.scatter(b, broadcast=True, hash=False)
    else:
        # Shared filesystem: every worker must see the scene at the same (absolute) path.
        tasks = [
            Task(t.frame, str(Path(t.scene).resolve()) if Path(t.scene).exists() else t.scene,
                 t.camera, t.samples, t.anim_frame)
            for t in tasks
        ]
    futures = {}
    for t in tasks:
        f = client.submit(
            render_chunk,
            job.trayecto,
            t,
            job.spp,
            list(job.render_args),
            job.threads_per_task,
            bundles.get(t.scene),
            key=f"trayecto-frame{t.frame}-samples{t.samples[0]}-{t.samples[1]}-{os.urandom(4).hex()}",
            retries=job.retries,
            pure=False,
        )
        futures[f] = t
    parts: dict[int, list[tuple[Task, bytes]]] = {}
    done = 0
    if progress:
        progress(0, len(tasks))
    try:
        for f in as_completed(list(futures)):
            t = futures[f]
            try:
                data = f.result()
            except FarmError:
                raise
            except Exception as e:  # a worker-side error after the retries ran out
                raise FarmError(
                    f"chunk {t.samples[0]}..{t.samples[1]} of frame {t.frame} failed: {e}"
                ) from e
            parts.setdefault(t.frame, []).append((t, data))
            done += 1
            if progress:
                progress(done, len(tasks))
    finally:
        for f in futures:
            f.cancel()
    outputs = []
    for i in range(len(job.frames())):
        outputs.append(merge_parts(merge_trayecto or job.trayecto, parts[i], job.frame_output(i)))
    return outputs


def merge_parts(trayecto: str, parts: Iterable[tuple[Task, bytes]], output: Path) -> Path:
    """Writes the parts to a temporary folder and runs ``trayecto merge`` on them."""
    with tempfile.TemporaryDirectory(prefix="trayecto-merge-") as d:
        paths = []
        for t, data in parts:
            p = Path(d) / f"part_{t.samples[0]:07d}_{t.samples[1]:07d}.trp"
            p.write_bytes(data)
            paths.append(str(p))
        cmd = [trayecto, "merge", *paths, "-o", str(output)]
        try:
            r = subprocess.run(cmd, capture_output=True, text=True)
        except FileNotFoundError:
            raise FarmError(f"cannot run '{trayecto}' to merge the parts") from None
        if r.returncode != 0:
            raise FarmError(f"trayecto merge failed (exit {r.returncode}): {r.stderr.strip()}")
    return output
