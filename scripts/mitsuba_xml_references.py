#!/usr/bin/env python3
"""Renders Mitsuba 3's references for tests/mitsuba_xml.rs: the documentation scenes of
shared/scenes/mitsuba/scenes/ at a tenth of their resolution, with Mitsuba 3 itself.

    python3 -m venv target/mitsuba-venv && target/mitsuba-venv/bin/pip install mitsuba numpy
    target/mitsuba-venv/bin/python scripts/mitsuba_xml_references.py [SPP] [NAME...]

Each scene and the files it includes are copied to a scratch folder with the film's width and
height divided by 10 (the test renders the original files at the same size: the field of view
depends only on the aspect ratio), rendered with scalar_rgb at SPP samples per pixel (default
4096) and written as tests/references/mitsuba_xml/NAME.exr (RGB, float32).
"""
import os
import re
import shutil
import sys
import tempfile

import mitsuba as mi

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SHARED = os.environ.get("TRAYECTO_SHARED", os.path.join(ROOT, "..", "shared"))
SCENES = os.path.join(SHARED, "scenes", "mitsuba", "scenes")
COMMON = os.path.join(SHARED, "scenes", "mitsuba", "common")
OUT = os.path.join(ROOT, "tests", "references", "mitsuba_xml")

# The scenes the test compares, by plugin family (keep in step with tests/mitsuba_xml.rs).
NAMES = [
    "bsdf_diffuse_plain", "bsdf_diffuse_textured", "bsdf_conductor_gold",
    "bsdf_dielectric_glass", "bsdf_roughconductor_copper", "bsdf_roughdielectric_rough",
    "bsdf_plastic_default", "bsdf_roughplastic_ggx", "bsdf_blendbsdf", "bsdf_twosided_cbox",
    "texture_checkerboard", "emitter_spot_no_texture", "sensor_thinlens", "sensor_orthographic",
    "shape_rectangle", "shape_sphere_basic", "shape_cylinder_twosided", "shape_disk",
    "shape_ply_bunny", "integrator_depth_2", "integrator_direct_both",
    "medium_homogeneous_sss",
]


def shrink(text):
    def div(m):
        return '%s%d"' % (m.group(1), max(1, int(m.group(2)) // 10))
    return re.sub(r'(<integer name="(?:width|height)" value=")(\d+)"', div, text)


def main():
    spp = int(sys.argv[1]) if len(sys.argv) > 1 else 4096
    names = sys.argv[2:] or NAMES
    mi.set_variant("scalar_rgb")
    os.makedirs(OUT, exist_ok=True)
    with tempfile.TemporaryDirectory() as top:
        # The layout the files' <path value="../../common"/> expects.
        tmp = os.path.join(top, "docs", "scenes")
        shutil.copytree(COMMON, os.path.join(top, "common"))
        for dirpath, _, files in os.walk(SCENES):
            rel = os.path.relpath(dirpath, SCENES)
            os.makedirs(os.path.join(tmp, rel), exist_ok=True)
            for f in files:
                src = os.path.join(dirpath, f)
                dst = os.path.join(tmp, rel, f)
                if f.endswith(".xml"):
                    with open(src) as fi, open(dst, "w") as fo:
                        fo.write(shrink(fi.read()))
                else:
                    shutil.copy(src, dst)
        mi.file_resolver().append(tmp)
        mi.file_resolver().append(os.path.join(top, "common"))
        for name in names:
            scene = mi.load_file(os.path.join(tmp, name + ".xml"), spp=spp)
            img = mi.render(scene, spp=spp, seed=1)
            bmp = mi.Bitmap(img[:, :, :3] if img.shape[2] > 3 else img)
            bmp.write(os.path.join(OUT, name + ".exr"))
            print(name, img.shape)


if __name__ == "__main__":
    main()
