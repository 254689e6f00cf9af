#!/usr/bin/env python3
"""Translates a pbrt-v4 scene of the subset the Bitterli scenes use into Mitsuba 3 scene XML.

    scripts/pbrt_to_mitsuba.py SCENE.pbrt OUT_DIR

writes OUT_DIR/scene.xml and OUT_DIR/meshes/*.ply (inline `trianglemesh` shapes; Mitsuba's XML
has no inline meshes). `plymesh` files are referenced where they are (a path relative to OUT_DIR).
What it translates, and how (pbrt-v4's semantics on the left, Mitsuba 3's on the right):

  Camera "perspective" fov        sensor perspective, fov_axis "smaller" (pbrt's fov spans the
                                  shorter image side); to_world = inverse(camera transform) with
                                  x negated (pbrt's camera space is left-handed, Mitsuba's not)
  Film xresolution/yresolution    hdrfilm width/height
  PixelFilter box/triangle/gauss  rfilter box/tent/gaussian (radius/stddev as given)
  Sampler pixelsamples            independent sampler sample_count
  Integrator path/volpath maxdepth  path max_depth = maxdepth + 1 (Mitsuba counts vertices)
  diffuse reflectance             twosided diffuse (pbrt's opaque materials have two sides)
  conductor eta/k (rgb), roughness  twosided conductor / roughconductor ggx (alpha = roughness, or
                                  sqrt(roughness) with remaproughness, pbrt-v4's RoughnessToAlpha)
  dielectric eta, roughness       dielectric / roughdielectric ggx
  AreaLightSource diffuse L (rgb) area emitter radiance
  Shape trianglemesh/plymesh/sphere  ply/ply/sphere, with the current transform
  Transform, ConcatTransform, Translate, Scale, AttributeBegin/End

Anything else stops the script with the directive's name: the output would not be the same
scene, so a comparison of the two would prove nothing.
"""

import math
import os
import re
import struct
import sys

TOKEN = re.compile(r'"[^"]*"|\[|\]|[^\s\[\]"]+')


def tokens(text):
    """pbrt tokens: quoted strings, brackets and bare words; `#` outside quotes ends the line."""
    for line in text.splitlines():
        quoted = False
        for i, ch in enumerate(line):
            if ch == '"':
                quoted = not quoted
            elif ch == "#" and not quoted:
                line = line[:i]
                break
        yield from TOKEN.findall(line)


class Unsupported(Exception):
    pass


def parse(text):
    """Directives as (name, [args], {param: (type, values)})."""
    toks = list(tokens(text))
    i, out = 0, []
    while i < len(toks):
        name = toks[i]
        i += 1
        args = []
        params = {}
        # Positional arguments: strings or a bracketed number list (Transform), numbers.
        while i < len(toks) and not re.match(r"^[A-Z][A-Za-z]+$", toks[i]):
            t = toks[i]
            if t.startswith('"') and " " in t.strip('"') and i + 1 < len(toks):
                ty, pname = t.strip('"').split(None, 1)
                i += 1
                vals = []
                if toks[i] == "[":
                    i += 1
                    while toks[i] != "]":
                        vals.append(toks[i])
                        i += 1
                    i += 1
                else:
                    vals.append(toks[i])
                    i += 1
                params[pname] = (ty, [v.strip('"') if v.startswith('"') else v for v in vals])
            elif t == "[":
                i += 1
                while toks[i] != "]":
                    args.append(toks[i])
                    i += 1
                i += 1
            else:
                args.append(t.strip('"') if t.startswith('"') else t)
                i += 1
        out.append((name, args, params))
    return out


def matmul(a, b):
    return [[sum(a[r][k] * b[k][c] for k in range(4)) for c in range(4)] for r in range(4)]


def identity():
    return [[1.0 if r == c else 0.0 for c in range(4)] for r in range(4)]


def from_pbrt(vals):
    """pbrt's 16 numbers are column-major (the translation is last)."""
    v = [float(x) for x in vals]
    return [[v[c * 4 + r] for c in range(4)] for r in range(4)]


def inverse(m):
    a = [row[:] + [1.0 if r == c else 0.0 for c in range(4)] for r, row in enumerate(m)]
    for c in range(4):
        p = max(range(c, 4), key=lambda r: abs(a[r][c]))
        a[c], a[p] = a[p], a[c]
        d = a[c][c]
        a[c] = [x / d for x in a[c]]
        for r in range(4):
            if r != c:
                f = a[r][c]
                a[r] = [x - f * y for x, y in zip(a[r], a[c])]
    return [row[4:] for row in a]


def matrix_xml(m):
    return '<matrix value="%s"/>' % " ".join("%.9g" % m[r][c] for r in range(4) for c in range(4))


def num(params, key, default):
    return float(params[key][1][0]) if key in params else default


def rgb(params, key, default):
    if key not in params:
        return default
    ty, vals = params[key]
    if ty == "rgb":
        return [float(x) for x in vals]
    if ty == "float":
        return [float(vals[0])] * 3
    raise Unsupported(f'"{ty} {key}" (only rgb and float values are translated)')


def write_ply(path, pos, idx, nrm, uv):
    with open(path, "wb") as f:
        head = ["ply", "format binary_little_endian 1.0", f"element vertex {len(pos) // 3}",
                "property float x", "property float y", "property float z"]
        if nrm:
            head += ["property float nx", "property float ny", "property float nz"]
        if uv:
            head += ["property float u", "property float v"]
        head += [f"element face {len(idx) // 3}", "property list uchar int vertex_indices", "end_header"]
        f.write(("\n".join(head) + "\n").encode())
        for v in range(len(pos) // 3):
            row = pos[3 * v:3 * v + 3] + (nrm[3 * v:3 * v + 3] if nrm else []) + (uv[2 * v:2 * v + 2] if uv else [])
            f.write(struct.pack("<%df" % len(row), *row))
        for t in range(len(idx) // 3):
            f.write(struct.pack("<B3i", 3, *idx[3 * t:3 * t + 3]))


def translate(src, out_dir):
    text = open(src).read()
    base = os.path.dirname(os.path.abspath(src))
    os.makedirs(os.path.join(out_dir, "meshes"), exist_ok=True)
    ctm, stack = identity(), []
    material, area = None, None
    materials = {}
    camera_m, fov, res, filt, spp, depth = None, 90.0, (1280, 720), None, 16, 5
    world, shapes, n_mesh = False, [], 0
    for name, args, params in parse(text):
        if name in ("Transform", "ConcatTransform"):
            m = from_pbrt(args or params)
            ctm = m if name == "Transform" else matmul(ctm, m)
        elif name == "Translate":
            t = identity()
            for k in range(3):
                t[k][3] = float(args[k])
            ctm = matmul(ctm, t)
        elif name == "Scale":
            s = identity()
            for k in range(3):
                s[k][k] = float(args[k])
            ctm = matmul(ctm, s)
        elif name == "Camera":
            if args[0] != "perspective":
                raise Unsupported(f'Camera "{args[0]}"')
            camera_m = ctm
            fov = num(params, "fov", 90.0)
        elif name == "Film":
            res = (int(num(params, "xresolution", 1280)), int(num(params, "yresolution", 720)))
        elif name == "PixelFilter":
            kind = {"box": "box", "triangle": "tent", "gaussian": "gaussian"}.get(args[0])
            if kind is None:
                raise Unsupported(f'PixelFilter "{args[0]}"')
            filt = (kind, num(params, "xradius", 1.5 if kind == "gaussian" else 0.5), num(params, "sigma", 0.5))
        elif name == "Sampler":
            spp = int(num(params, "pixelsamples", 16))
        elif name == "Integrator":
            if args[0] not in ("path", "volpath"):
                raise Unsupported(f'Integrator "{args[0]}"')
            depth = int(num(params, "maxdepth", 5))
        elif name == "Accelerator":
            pass
        elif name == "WorldBegin":
            world, ctm = True, identity()
        elif name == "AttributeBegin":
            stack.append((ctm, material, area))
        elif name == "AttributeEnd":
            ctm, material, area = stack.pop()
        elif name == "MakeNamedMaterial":
            materials[args[0]] = bsdf_xml(params["type"][1][0], params)
        elif name == "NamedMaterial":
            material = materials[args[0]]
        elif name == "Material":
            material = bsdf_xml(args[0], params)
        elif name == "AreaLightSource":
            if args[0] != "diffuse" or set(params) - {"L"}:
                raise Unsupported(f'AreaLightSource "{args[0]}" with {sorted(params)}')
            area = rgb(params, "L", [1, 1, 1])
        elif name == "Shape":
            kind = args[0]
            if kind == "trianglemesh":
                n_mesh += 1
                rel = f"meshes/mesh{n_mesh:03d}.ply"
                f = lambda k: [float(x) for x in params[k][1]] if k in params else []
                write_ply(os.path.join(out_dir, rel), f("P"), [int(x) for x in params["indices"][1]], f("N"), f("uv"))
                body = f'<string name="filename" value="{rel}"/>'
                ty = "ply"
            elif kind == "plymesh":
                rel = os.path.relpath(os.path.join(base, params["filename"][1][0]), out_dir)
                body = f'<string name="filename" value="{rel}"/>'
                ty = "ply"
            elif kind == "sphere":
                body = f'<float name="radius" value="{num(params, "radius", 1.0)}"/>'
                ty = "sphere"
            else:
                raise Unsupported(f'Shape "{kind}"')
            for k in params:
                if k not in ("P", "N", "uv", "indices", "filename", "radius"):
                    raise Unsupported(f'Shape "{kind}" parameter "{k}"')
            emitter = ""
            if area is not None:
                emitter = '<emitter type="area"><rgb name="radiance" value="%s"/></emitter>' % ", ".join("%.9g" % x for x in area)
            shapes.append(f'<shape type="{ty}">{body}<transform name="to_world">{matrix_xml(ctm)}</transform>'
                          f'{material or bsdf_xml("diffuse", {})}{emitter}</shape>')
        else:
            raise Unsupported(name)
    if camera_m is None:
        raise Unsupported("a file without a Camera")
    flip = identity()
    flip[0][0] = -1.0
    to_world = matmul(inverse(camera_m), flip)
    rf = ""
    if filt:
        kind, radius, sigma = filt
        rf = {"box": '<rfilter type="box"/>',
              "tent": f'<rfilter type="tent"><float name="radius" value="{radius}"/></rfilter>',
              "gaussian": f'<rfilter type="gaussian"><float name="stddev" value="{sigma}"/></rfilter>'}[kind]
    xml = [f'<scene version="3.0.0">',
           f'<integrator type="path"><integer name="max_depth" value="{depth + 1}"/></integrator>',
           f'<sensor type="perspective"><string name="fov_axis" value="smaller"/><float name="fov" value="{fov}"/>',
           f'<transform name="to_world">{matrix_xml(to_world)}</transform>',
           f'<sampler type="independent"><integer name="sample_count" value="{spp}"/></sampler>',
           f'<film type="hdrfilm"><integer name="width" value="{res[0]}"/><integer name="height" value="{res[1]}"/>{rf}</film></sensor>']
    xml += shapes
    xml.append("</scene>")
    with open(os.path.join(out_dir, "scene.xml"), "w") as f:
        f.write("\n".join(xml) + "\n")


def twosided(bsdf):
    """pbrt-v4's opaque materials reflect on both sides; Mitsuba's are black from behind."""
    return f'<bsdf type="twosided">{bsdf}</bsdf>'


def bsdf_xml(kind, params):
    known = {"type", "reflectance", "eta", "k", "roughness", "uroughness", "vroughness", "remaproughness"}
    extra = set(params) - known
    if extra:
        raise Unsupported(f'material "{kind}" parameters {sorted(extra)}')
    if kind == "diffuse":
        r = rgb(params, "reflectance", [0.5] * 3)
        return twosided('<bsdf type="diffuse"><rgb name="reflectance" value="%s"/></bsdf>' % ", ".join("%.9g" % x for x in r))
    rough = num(params, "uroughness", num(params, "roughness", 0.0))
    if num(params, "vroughness", rough) != rough:
        raise Unsupported("anisotropic roughness")
    remap = params.get("remaproughness", ("bool", ["true"]))[1][0] == "true"
    alpha = math.sqrt(rough) if remap else rough
    if kind == "conductor":
        eta, k = rgb(params, "eta", None), rgb(params, "k", None)
        if eta is None or k is None:
            raise Unsupported("a conductor without rgb eta and k")
        inner = '<rgb name="eta" value="%s"/><rgb name="k" value="%s"/>' % (
            ", ".join("%.9g" % x for x in eta), ", ".join("%.9g" % x for x in k))
        if alpha == 0:
            return twosided(f'<bsdf type="conductor">{inner}</bsdf>')
        return twosided(f'<bsdf type="roughconductor"><string name="distribution" value="ggx"/><float name="alpha" value="{alpha}"/>{inner}</bsdf>')
    if kind == "dielectric":
        eta = num(params, "eta", 1.5)
        inner = f'<float name="int_ior" value="{eta}"/><float name="ext_ior" value="1"/>'
        if alpha == 0:
            return f'<bsdf type="dielectric">{inner}</bsdf>'
        return f'<bsdf type="roughdielectric"><string name="distribution" value="ggx"/><float name="alpha" value="{alpha}"/>{inner}</bsdf>'
    raise Unsupported(f'material "{kind}"')


def main():
    if len(sys.argv) != 3:
        print(__doc__)
        sys.exit(2)
    try:
        translate(sys.argv[1], sys.argv[2])
    except Unsupported as e:
        print(f"error: {sys.argv[1]}: {e} cannot be translated", file=sys.stderr)
        sys.exit(1)


if __name__ == "__main__":
    main()
