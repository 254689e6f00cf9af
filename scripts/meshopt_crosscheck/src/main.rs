//! One-off cross-check: the pure-Rust decoder (meshoptimizer-rs) against the C++ reference
//! (meshopt crate) on every compressed view of the test files and on synthetic streams.
use meshoptimizer_rs::{Limits, Workspace, codec as r};

fn ws() -> Workspace { Workspace::new(Limits::default()) }

#[derive(Clone, Copy)]
struct V<const N: usize>([u8; N]);
impl<const N: usize> Default for V<N> { fn default() -> Self { V([0; N]) } }

fn cpp_vertices(src: &[u8], count: usize, stride: usize) -> Vec<u8> {
    macro_rules! s { ($($n:literal)*) => { match stride { $($n => meshopt::decode_vertex_buffer::<V<$n>>(src, count).unwrap().iter().flat_map(|v| v.0).collect(),)* _ => panic!() } } }
    s!(4 8 12 16 20 24 28 32)
}

fn cpp_filter(data: &mut Vec<u8>, filter: &str, stride: usize) {
    match (filter, stride) {
        ("OCTAHEDRAL", 4) => { let mut v: Vec<[i8;4]> = data.chunks(4).map(|c| [c[0] as i8,c[1] as i8,c[2] as i8,c[3] as i8]).collect(); meshopt::decode_filter_oct(&mut v); *data = v.iter().flat_map(|e| e.map(|x| x as u8)).collect(); }
        ("OCTAHEDRAL", 8) => { let mut v: Vec<[i16;4]> = data.chunks(8).map(|c| [0,2,4,6].map(|k| i16::from_le_bytes([c[k],c[k+1]]))).collect(); meshopt::decode_filter_oct(&mut v); *data = v.iter().flat_map(|e| e.iter().flat_map(|x| x.to_le_bytes()).collect::<Vec<_>>()).collect(); }
        ("QUATERNION", 8) => { let mut v: Vec<[i16;4]> = data.chunks(8).map(|c| [0,2,4,6].map(|k| i16::from_le_bytes([c[k],c[k+1]]))).collect(); meshopt::decode_filter_quat(&mut v); *data = v.iter().flat_map(|e| e.iter().flat_map(|x| x.to_le_bytes()).collect::<Vec<_>>()).collect(); }
        ("COLOR", 4) => { let mut v: Vec<[u8;4]> = data.chunks(4).map(|c| [c[0],c[1],c[2],c[3]]).collect(); meshopt::decode_filter_color(&mut v); *data = v.concat(); }
        ("COLOR", 8) => { let mut v: Vec<[u16;4]> = data.chunks(8).map(|c| [0,2,4,6].map(|k| u16::from_le_bytes([c[k],c[k+1]]))).collect(); meshopt::decode_filter_color(&mut v); *data = v.iter().flat_map(|e| e.iter().flat_map(|x| x.to_le_bytes()).collect::<Vec<_>>()).collect(); }
        ("EXPONENTIAL", _) => { let mut v: Vec<[u32;1]> = data.chunks(4).map(|c| [u32::from_le_bytes([c[0],c[1],c[2],c[3]])]).collect(); meshopt::decode_filter_exp(&mut v); *data = v.iter().flat_map(|e| e[0].to_le_bytes()).collect(); }
        _ => {}
    }
}

fn rust_filter(data: &mut [u8], filter: &str, count: usize, stride: usize) {
    let w = &mut ws();
    match filter {
        "OCTAHEDRAL" => r::decode_filter_oct(data, count, stride, w).unwrap(),
        "QUATERNION" => r::decode_filter_quat(data, count, stride, w).unwrap(),
        "COLOR" => r::decode_filter_color(data, count, stride, w).unwrap(),
        "EXPONENTIAL" => r::decode_filter_exp(data, count, stride, w).unwrap(),
        _ => {}
    }
}

fn check(name: &str, mode: &str, filter: &str, src: &[u8], count: usize, stride: usize) -> bool {
    let (mut a, mut b): (Vec<u8>, Vec<u8>) = match mode {
        "ATTRIBUTES" => (cpp_vertices(src, count, stride), r::decode_vertex_buffer(count, stride, src, &mut ws()).unwrap()),
        "TRIANGLES" => (if stride == 2 { meshopt::decode_index_buffer::<u16>(src, count).unwrap().iter().flat_map(|i| i.to_le_bytes()).collect() } else { meshopt::decode_index_buffer::<u32>(src, count).unwrap().iter().flat_map(|i| i.to_le_bytes()).collect() },
                        r::decode_index_buffer(count, stride, src, &mut ws()).unwrap()),
        _ => (if stride == 2 { meshopt::decode_index_sequence::<u16>(src, count).unwrap().iter().flat_map(|i| i.to_le_bytes()).collect() } else { meshopt::decode_index_sequence::<u32>(src, count).unwrap().iter().flat_map(|i| i.to_le_bytes()).collect() },
                        r::decode_index_sequence(count, stride, src, &mut ws()).unwrap()),
    };
    cpp_filter(&mut a, filter, stride);
    rust_filter(&mut b, filter, count, stride);
    let same = a == b;
    if !same {
        let comp = if filter == "COLOR" && stride == 8 || filter == "OCTAHEDRAL" && stride == 8 { 2 } else { 1 };
        let mut n = 0; let mut maxd = 0i64;
        for (x, y) in a.chunks(comp).zip(b.chunks(comp)) {
            let (x, y) = if comp == 2 { (i16::from_le_bytes([x[0],x[1]]) as i64, i16::from_le_bytes([y[0],y[1]]) as i64) } else { (x[0] as i8 as i64, y[0] as i8 as i64) };
            if x != y { n += 1; maxd = maxd.max((x - y).abs()); }
        }
        let comps = a.len() / comp;
        println!("  {n} of {comps} components differ, by at most {maxd}");
        if filter == "COLOR" { let mut m=0i64; for (x,y) in a.chunks(2).zip(b.chunks(2)) { let x=u16::from_le_bytes([x[0],x[1]]) as i64; let y=u16::from_le_bytes([y[0],y[1]]) as i64; m=m.max((x-y).abs()); } println!("  as u16: max diff {m}"); }
    }
    println!("{name}: {mode} {filter} stride {stride} count {count}: {} bytes, {}", a.len(), if same { "identical" } else { "DIFFERENT" });
    same
}

fn main() {
    let mut all = true;
    for f in std::env::args().skip(1) {
        let b = std::fs::read(&f).unwrap();
        let n = u32::from_le_bytes(b[12..16].try_into().unwrap()) as usize;
        let j: serde_json::Value = serde_json::from_slice(&b[20..20 + n]).unwrap();
        let bin_start = 20 + n + 8;
        let bin = &b[bin_start..];
        for (i, v) in j["bufferViews"].as_array().unwrap().iter().enumerate() {
            for ext in ["EXT_meshopt_compression", "KHR_meshopt_compression"] {
                let e = &v["extensions"][ext];
                if !e.is_object() { continue; }
                let off = e["byteOffset"].as_u64().unwrap_or(0) as usize;
                let len = e["byteLength"].as_u64().unwrap() as usize;
                let src = &bin[off..off + len];
                all &= check(&format!("{f} view {i} ({ext})"), e["mode"].as_str().unwrap(), e["filter"].as_str().unwrap_or("NONE"), src, e["count"].as_u64().unwrap() as usize, e["byteStride"].as_u64().unwrap() as usize);
            }
        }
    }
    // Synthetic streams for what the files lack: u32 triangles, index sequences, vertex codec v0
    // and v1 at 16/32-byte strides, quaternion, colour (8 and 16 bit), 16-bit octahedral.
    let mut s = 12345u32;
    let mut rnd = || { s ^= s << 13; s ^= s >> 17; s ^= s << 5; s };
    let tri: Vec<u32> = (0..3000).map(|_| rnd() % 100_000).collect();
    all &= check("synthetic", "TRIANGLES", "NONE", &meshopt::encode_index_buffer(&tri, 100_000).unwrap(), 3000, 4);
    let seq: Vec<u32> = (0..2001).map(|_| rnd() % 70_000).collect();
    let enc = meshopt::encode_index_sequence(&seq, 70_000).unwrap();
    all &= check("synthetic", "INDICES", "NONE", &enc, 2001, 4);
    let seq16: Vec<u32> = seq.iter().map(|x| x % 60_000).collect();
    all &= check("synthetic", "INDICES", "NONE", &meshopt::encode_index_sequence(&seq16, 60_000).unwrap(), 2001, 2);
    let verts: Vec<V<16>> = (0..1000).map(|i| { let mut v = [0u8; 16]; for k in 0..16 { v[k] = ((i * (k + 1)) as u32 ^ (rnd() & 3)) as u8; } V(v) }).collect();
    let raw: Vec<u8> = verts.iter().flat_map(|v| v.0).collect();
    for ver in [0, 1] {
        let enc = r::encode_vertex_buffer(&raw, 1000, 16, if ver == 0 { r::VertexEncoding::new(0, 2).unwrap() } else { r::VertexEncoding::DEFAULT }, &mut ws()).unwrap();
        all &= check(&format!("synthetic v{ver}"), "ATTRIBUTES", "NONE", &enc, 1000, 16);
        let enc = meshopt::encode_vertex_buffer_level(&verts, 3, Some(ver)).unwrap();
        all &= check(&format!("synthetic C++-encoded v{ver}"), "ATTRIBUTES", "NONE", &enc, 1000, 16);
    }
    let quats: Vec<[f32; 4]> = (0..500).map(|_| { let q = [0,1,2,3].map(|_| (rnd() % 2001) as f32 / 1000.0 - 1.0); let l = q.iter().map(|x| x * x).sum::<f32>().sqrt(); q.map(|x| x / l) }).collect();
    let qe: Vec<u8> = meshopt::encode_filter_quat(&quats, 12).iter().flat_map(|e| e.iter().flat_map(|x| x.to_le_bytes()).collect::<Vec<_>>()).collect();
    let enc = r::encode_vertex_buffer(&qe, 500, 8, r::VertexEncoding::DEFAULT, &mut ws()).unwrap();
    all &= check("synthetic", "ATTRIBUTES", "QUATERNION", &enc, 500, 8);
    let cols: Vec<[f32; 4]> = (0..500).map(|_| [0,1,2,3].map(|_| (rnd() % 1001) as f32 / 1000.0)).collect();
    let c8: Vec<u8> = meshopt::encode_filter_color::<u8>(&cols, 8).concat();
    let enc = r::encode_vertex_buffer(&c8, 500, 4, r::VertexEncoding::DEFAULT, &mut ws()).unwrap();
    all &= check("synthetic", "ATTRIBUTES", "COLOR", &enc, 500, 4);
    let c16: Vec<u8> = meshopt::encode_filter_color::<u16>(&cols, 12).iter().flat_map(|e| e.iter().flat_map(|x| x.to_le_bytes()).collect::<Vec<_>>()).collect();
    let enc = r::encode_vertex_buffer(&c16, 500, 8, r::VertexEncoding::DEFAULT, &mut ws()).unwrap();
    all &= check("synthetic", "ATTRIBUTES", "COLOR", &enc, 500, 8);
    let o16: Vec<u8> = meshopt::encode_filter_oct::<i16>(&quats, 14).iter().flat_map(|e| e.iter().flat_map(|x| x.to_le_bytes()).collect::<Vec<_>>()).collect();
    let enc = r::encode_vertex_buffer(&o16, 500, 8, r::VertexEncoding::DEFAULT, &mut ws()).unwrap();
    all &= check("synthetic", "ATTRIBUTES", "OCTAHEDRAL", &enc, 500, 8);
    println!("{}", if all { "ALL IDENTICAL" } else { "MISMATCH" });
}
