// Replaces every texture image of a glTF with a KTX2 (Basis Universal) file encoded by the
// `basisu` command-line encoder, and marks KHR_texture_basisu required (no PNG fallback is kept).
// Usage: node scripts/gltf_ktx2.mjs IN.glb OUT.glb BASISU_BINARY [basisu options...]
// Run by scripts/make_gltf_files.sh, which installs @gltf-transform and the encoder.
import { execFileSync } from 'node:child_process';
import { mkdtempSync, readFileSync, writeFileSync, rmSync } from 'node:fs';
import { tmpdir } from 'node:os';
import { join } from 'node:path';
import { createRequire } from 'node:module';

const require = createRequire(join(process.cwd(), 'target/gltf-files-npm/package.json'));
const { NodeIO } = require('@gltf-transform/core');
const { ALL_EXTENSIONS, KHRTextureBasisu } = require('@gltf-transform/extensions');

const [input, output, basisu, ...options] = process.argv.slice(2);
const io = new NodeIO().registerExtensions(ALL_EXTENSIONS);
const doc = await io.read(input);
doc.createExtension(KHRTextureBasisu).setRequired(true);
const dir = mkdtempSync(join(tmpdir(), 'gltf-ktx2-'));
doc.getRoot().listTextures().forEach((texture, i) => {
  const png = join(dir, `t${i}.png`);
  const ktx2 = join(dir, `t${i}.ktx2`);
  writeFileSync(png, texture.getImage());
  execFileSync(basisu, ['-ktx2', '-file', png, '-output_file', ktx2, ...options], { stdio: 'ignore' });
  texture.setImage(readFileSync(ktx2)).setMimeType('image/ktx2');
});
await io.write(output, doc);
rmSync(dir, { recursive: true });
