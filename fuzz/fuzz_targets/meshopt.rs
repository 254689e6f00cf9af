//! Fuzz target: meshopt-compressed buffer views (EXT_/KHR_meshopt_compression, decoded by the
//! pure-Rust `meshoptimizer-rs`). The first bytes choose the extension, mode, filter, stride and
//! count; the rest is the compressed stream, wrapped in a GLB whose one buffer view carries it
//! and whose accessor reads the decoded positions. Loading must return Ok or Err, never panic.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if data.len() < 4 {
        return;
    }
    let (head, stream) = data.split_at(4);
    let ext = ["EXT_meshopt_compression", "KHR_meshopt_compression"][(head[0] & 1) as usize];
    let mode = ["ATTRIBUTES", "TRIANGLES", "INDICES"][(head[0] >> 1) as usize % 3];
    let filter =
        ["NONE", "OCTAHEDRAL", "QUATERNION", "EXPONENTIAL", "COLOR"][(head[1] % 5) as usize];
    let stride = match mode {
        "ATTRIBUTES" => 4 * (1 + (head[2] as usize % 64)),
        _ => 2 << (head[2] & 1),
    };
    let count = u16::from_le_bytes([head[3], head[0] >> 4]) as usize;
    let mut bin = stream.to_vec();
    while bin.len() % 4 != 0 {
        bin.push(0);
    }
    let json = format!(
        r#"{{"asset":{{"version":"2.0"}},"extensionsUsed":["{ext}"],
 "buffers":[{{"byteLength":{bl}}}],
 "bufferViews":[{{"buffer":0,"byteLength":{vl},"byteStride":{stride},
   "extensions":{{"{ext}":{{"buffer":0,"byteLength":{sl},"byteStride":{stride},"count":{count},"mode":"{mode}","filter":"{filter}"}}}}}}],
 "accessors":[{{"bufferView":0,"componentType":5126,"count":{ac},"type":"VEC3","min":[-1,-1,-1],"max":[1,1,1]}}],
 "meshes":[{{"primitives":[{{"attributes":{{"POSITION":0}}}}]}}],
 "nodes":[{{"mesh":0}}],"scenes":[{{"nodes":[0]}}]}}"#,
        bl = bin.len(),
        vl = count * stride,
        sl = stream.len(),
        ac = if stride >= 12 { count } else { 0 },
    );
    let mut j = json.into_bytes();
    while j.len() % 4 != 0 {
        j.push(b' ');
    }
    let total = 12 + 8 + j.len() + 8 + bin.len();
    let mut glb = Vec::with_capacity(total);
    glb.extend(b"glTF");
    glb.extend(2u32.to_le_bytes());
    glb.extend((total as u32).to_le_bytes());
    glb.extend((j.len() as u32).to_le_bytes());
    glb.extend(b"JSON");
    glb.extend(&j);
    glb.extend((bin.len() as u32).to_le_bytes());
    glb.extend(b"BIN\0");
    glb.extend(&bin);
    let dir = std::env::temp_dir().join("trayecto-fuzz-empty");
    let _ = std::fs::create_dir_all(&dir);
    let _ = trayecto::scene::load_bytes(&glb, &dir, "fuzz.glb");
});
