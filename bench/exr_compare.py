"""What the bench scripts that compare a Trayecto render with a reference image share: reading
an EXR (OpenEXR or mitsuba, whichever is installed), luminance, and the comparison they print
(luminance bias, R/G/B ratio of the means, relative error of the 4 x 4 blocks)."""
import numpy as np


def read(path):
    """An EXR's RGB as float64, rows top first."""
    try:
        import OpenEXR

        with OpenEXR.File(path) as f:
            ch = f.channels()
            rgb = ch["RGB"].pixels if "RGB" in ch else np.stack([ch[c].pixels for c in "RGB"], -1)
        return np.asarray(rgb, dtype=np.float64)[:, :, :3]
    except ImportError:
        import mitsuba as mi

        mi.set_variant("scalar_rgb")
        return np.array(mi.Bitmap(path), dtype=np.float64)[:, :, :3]


def lum(a):
    return a @ [0.2126, 0.7152, 0.0722]


def compare(t, p, n=4):
    """`t` against the reference `p`: (luminance bias, R/G/B ratio of the means, relative errors
    of the n x n blocks' luminance sums)."""
    bias = lum(t).sum() / lum(p).sum() - 1
    h, w = t.shape[:2]
    block = lambda a: lum(a)[: h // n * n, : w // n * n].reshape(n, h // n, n, w // n).sum(axis=(1, 3))
    bt, bp = block(t), block(p)
    e = np.abs(bt - bp) / np.maximum(bp, 1e-9)
    ratio = t.reshape(-1, 3).sum(0) / p.reshape(-1, 3).sum(0)
    return bias, ratio, e


def summary(t, p):
    """The comparison as the scripts print it."""
    bias, ratio, e = compare(t, p)
    return (f"bias {100 * bias:+.2f} %, R/G/B {ratio.round(3)}, "
            f"4x4 blocks mean {100 * e.mean():.1f} % worst {100 * e.max():.1f} %")
