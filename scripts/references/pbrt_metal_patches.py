#!/usr/bin/env python3
"""Measures the RGB conversion of pbrt-v4's named metals (src/spectrum) against pbrt-v4 itself.

For each metal (Cu, Au, Ag, Al) and incidence angle (0, 60 deg) it writes a pbrt-v4 scene -- an
orthographic view of a smooth `conductor` disk with `"spectrum eta" "metal-X-eta"` under a uniform
`infinite` light `rgb L [1 1 1]`, path depth 1 -- renders it with ../shared/tools/pbrt-v4/pbrt
(8x8, 16 spp), and prints the mean pixel beside (a) the spectral Fresnel reflectance computed from
Trayecto's tables under D65 (what pbrt integrates) and (b) the RGB Fresnel of Trayecto's converted
RGB eta and k. Needs mitsuba and numpy (pip) to read the EXRs. Run from the repository root:
    python3 scripts/references/pbrt_metal_patches.py
"""
import os, subprocess, tempfile
ROOT = os.path.normpath(os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", ".."))
PBRT = os.path.join(ROOT, "..", "shared", "tools", "pbrt-v4", "pbrt")
WORK = tempfile.mkdtemp(prefix="pbrt_metals_")
SCENE = """LookAt 0 0 5  0 0 0  0 1 0
Camera "orthographic" "float screenwindow" [-0.5 0.5 -0.5 0.5]
Sampler "independent" "integer pixelsamples" 16
Integrator "path" "integer maxdepth" 1
Film "rgb" "integer xresolution" 8 "integer yresolution" 8 "string filename" "{out}"
WorldBegin
LightSource "infinite" "rgb L" [1 1 1]
Material "conductor" "spectrum eta" "metal-{m}-eta" "spectrum k" "metal-{m}-k"
Rotate {tilt} 1 0 0
Shape "disk" "float radius" 10
"""
for m in ["Cu", "Au", "Ag", "Al"]:
    for tilt in [0, 60]:
        out = os.path.join(WORK, f"{m}_{tilt}.exr")
        path = os.path.join(WORK, f"{m}_{tilt}.pbrt")
        open(path, "w").write(SCENE.format(out=out, m=m, tilt=tilt))
        subprocess.run([PBRT, "--nthreads", "1", path], check=True, capture_output=True)
os.chdir(WORK)
import re, numpy as np, mitsuba as mi
mi.set_variant('scalar_rgb')
src=open(os.path.join(ROOT, 'src', 'spectrum', 'data.rs')).read()
def arr(name):
    m=re.search(r"pub const %s: \[[^\]]*\] = \[(.*?)\];"%name, src, re.S)
    return m.group(1)
X=np.array(eval('['+arr('CIE_X')+']'));Y=np.array(eval('['+arr('CIE_Y')+']'));Z=np.array(eval('['+arr('CIE_Z')+']'))
D=np.array(eval('['+arr('D65')+']')); lam=np.arange(360,831); d65=np.interp(lam, np.arange(360,831,5), D); d65*=Y.sum()/(d65*Y).sum()
M=np.array([[3.2404542,-1.5371385,-0.4985314],[-0.9692660,1.8760108,0.0415560],[0.0556434,-0.2040259,1.0572252]])
def rgb(s): return M@np.array([(X*s).sum(),(Y*s).sum(),(Z*s).sum()])/Y.sum()
def tab(n):
    t=eval('['+arr(n)+']'); a=np.array(t); return np.interp(lam,a[:,0],a[:,1],left=0,right=0)
def fr(c,eta,k):
    e=eta+1j*k; s2=1-c*c; ct=np.sqrt(1-s2/(e*e)); rp=(e*c-ct)/(e*c+ct); rs=(c-e*ct)/(c+e*ct); return (abs(rp)**2+abs(rs)**2)/2
for m in ['Cu','Au','Ag','Al']:
    eta=tab(m.upper()+'_ETA'); k=tab(m.upper()+'_K')
    er=rgb(eta*d65); kr=rgb(k*d65)
    for tilt in [0,60]:
        c=np.cos(np.radians(tilt))
        b=mi.Bitmap(f'{m}_{tilt}.exr'); img=np.array(b)[...,:3].reshape(-1,3).mean(0)
        spec=rgb(fr(c,eta,k)*d65); ours=np.array([fr(c,er[i],kr[i]) for i in range(3)])
        print(f"{m} {tilt:2d}deg pbrt-v4 {np.round(img,4)} spectral(tables) {np.round(spec,4)} trayecto-rgb {np.round(ours,4)} max|trayecto-pbrt| {abs(ours-img).max():.4f}")
