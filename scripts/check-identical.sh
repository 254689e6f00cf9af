#!/usr/bin/env bash
# Renders the same scenes with two trayecto binaries, to EXR, and compares the outputs byte for
# byte: exits non-zero naming every case that differs or fails. Used to show that a refactor
# leaves the images bit-identical.
#
#   scripts/check-identical.sh BEFORE_BIN AFTER_BIN
#
# Run from the repository root (scene paths use ../shared, as the tests do).
set -uo pipefail
if [ $# -ne 2 ]; then
  echo "usage: $0 BEFORE_BIN AFTER_BIN" >&2
  exit 2
fi
before="$1"
after="$2"
for b in "$before" "$after"; do
  [ -x "$b" ] || { echo "$b: not an executable" >&2; exit 2; }
done
shared=../shared/scenes
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT
small=(--width 64 --height 64 --spp 16 --quiet)

# name | scene | extra options
cases=(
  "cornell|cornell|"
  "cornell-sobol-grid|cornell|--sampler sobol --accel grid --threads 1"
  "boxtextured|$shared/gltf/BoxTextured/glTF-Binary/BoxTextured.glb|"
  "transmission|$shared/gltf/TransmissionTest/glTF-Binary/TransmissionTest.glb|"
  "normaltangent|$shared/gltf/NormalTangentTest/glTF/NormalTangentTest.gltf|"
  "fbx-cornell|$shared/fbx/cornell_seed_conventions.fbx|"
  "toml-example|scenes/example.toml|"
  "toml-glass|scenes/mitsuba/glass.toml|"
  "whitted|cornell|--integrator whitted"
  "whitted-glass|scenes/mitsuba/glass.toml|--integrator whitted --shading phong"
  "raycast-shaded|cornell|--integrator raycast --aov shaded"
  "raycast-normals|$shared/gltf/NormalTangentTest/glTF/NormalTangentTest.gltf|--integrator raycast --aov normals"
  "raycast-depth|cornell|--integrator raycast --aov depth"
  "raycast-albedo|$shared/gltf/BoxTextured/glTF-Binary/BoxTextured.glb|--integrator raycast --aov albedo"
  "raycast-uv|$shared/gltf/BoxTextured/glTF-Binary/BoxTextured.glb|--integrator raycast --aov uv"
  "raycast-barycentric|cornell|--integrator raycast --aov barycentric"
  # A thin-lens camera (the lens dimensions are drawn), specular and coated BSDFs (NEE skipped at
  # specular vertices), a many-light textured model, and the other samplers' streams.
  "pbrt-thin-lens|scenes/pbrt/screenwindow.pbrt|"
  "pbrt-roughness|scenes/pbrt/roughness.pbrt|"
  "pbrt-spectra|scenes/pbrt/spectra.pbrt|"
  "pbrt-metals|scenes/pbrt/metals.pbrt|"
  "pbrt-prism|scenes/pbrt/prism-bk7.pbrt|"
  "toycar|$shared/gltf-ext/ToyCar/glTF/ToyCar.gltf|"
  # ToyCar by its 2 720 emissive triangles alone: every light choice walks the light BVH.
  "toycar-emitters|$shared/gltf-ext/ToyCar/glTF/ToyCar.gltf|--default-light off"
  "toycar-bvh4|$shared/gltf-ext/ToyCar/glTF/ToyCar.gltf|--default-light off --light-sampler bvh"
  "toycar-power|$shared/gltf-ext/ToyCar/glTF/ToyCar.gltf|--default-light off --light-sampler power"
  "cornell-zsobol|cornell|--sampler zsobol"
  "cornell-independent-aov|cornell|--sampler independent --aov albedo,normal"
  # Every light type on its own (delta lights, lights at infinity, an image environment) and
  # participating media (homogeneous, grid, emissive): the volumetric path tracer's cases.
  "point|scenes/mitsuba/point.toml|"
  "spot|scenes/mitsuba/spot_soft.toml|"
  "directional|scenes/mitsuba/directional.toml|"
  "constant-env|scenes/mitsuba/constant_env.toml|"
  "envmap|scenes/mitsuba/envmap.toml|"
  "whitted-spot|scenes/mitsuba/spot.toml|--integrator whitted"
  "fog|scenes/media/fog_cornell.toml|"
  "cloud|scenes/media/cloud.toml|"
  "emissive-grid|scenes/pbrt/media/emissive_grid.pbrt|"
  "absorbing-glass|scenes/pbrt/media/absorbing_glass.pbrt|"
  # The light-path integrators on surfaces (a media-free scene keeps their surface code).
  "lighttracer|cornell|--integrator lighttracer"
  "lighttracer-point|scenes/mitsuba/point.toml|--integrator lighttracer"
  "bdpt|cornell|--integrator bdpt"
  "bdpt-glass|scenes/mitsuba/glass.toml|--integrator bdpt"
  "bdpt-envmap|scenes/mitsuba/envmap.toml|--integrator bdpt"
  # The photon integrators on diffuse and specular surfaces with an area light (scenes whose
  # SPPM and VCM images no change to their glossy, lens or infinite-light handling touches).
  "sppm|cornell|--integrator sppm"
  "vcm|cornell|--integrator vcm"
  "sppm-caustic|scenes/pbrt/caustic-through-glass.pbrt|--integrator sppm"
  "vcm-caustic|scenes/pbrt/caustic-through-glass.pbrt|--integrator vcm"
)

failed=0
for c in "${cases[@]}"; do
  IFS='|' read -r name scene extra <<<"$c"
  # shellcheck disable=SC2206
  opts=($extra)
  ok=1
  for side in before after; do
    bin="$before"; [ "$side" = after ] && bin="$after"
    if ! "$bin" render "$scene" -o "$tmp/$name.$side.exr" "${small[@]}" "${opts[@]}" \
        2>"$tmp/$name.$side.log"; then
      echo "FAIL $name: the $side binary failed:" >&2
      sed 's/^/    /' "$tmp/$name.$side.log" >&2
      ok=0
    fi
  done
  if [ $ok = 1 ]; then
    if cmp -s "$tmp/$name.before.exr" "$tmp/$name.after.exr"; then
      echo "same $name"
    else
      echo "DIFFERENT $name ($scene $extra)" >&2
      ok=0
    fi
  fi
  [ $ok = 1 ] || failed=$((failed + 1))
done
if [ $failed -gt 0 ]; then
  echo "$failed of ${#cases[@]} cases differ or failed" >&2
  exit 1
fi
echo "all ${#cases[@]} cases bit-identical"
