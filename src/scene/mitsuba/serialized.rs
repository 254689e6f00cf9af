//! Mitsuba's `.serialized` meshes: a sequence of shapes, each the little-endian u16 0x041C,
//! a u16 format version (3 or 4), then a zlib stream holding a u32 flag word, (version 4) a
//! NUL-terminated name, u64 vertex and triangle counts, the positions, then the normals,
//! texture coordinates and colours the flags announce, then the triangles' vertex indices
//! (u32, or u64 for more than 2³² vertices). Positions and attributes are f32, or f64 when the
//! double-precision flag is set. The file ends with a table of offsets, which is not needed:
//! the shapes are read in sequence, each stream's end giving the next shape's start.

use flate2::{Decompress, FlushDecompress, Status};

const HEADER: u16 = 0x041C;
const HAS_NORMALS: u32 = 0x0001;
const HAS_TEXCOORDS: u32 = 0x0002;
const HAS_COLORS: u32 = 0x0008;
const DOUBLE: u32 = 0x2000;
/// Largest decompressed shape accepted (bytes).
const MAX_SHAPE_BYTES: u64 = 4 << 30;

/// One decoded shape. `uvs` are as stored (Mitsuba's convention: v down).
#[derive(Debug, Default)]
pub struct SerializedMesh {
    pub positions: Vec<f32>,
    pub indices: Vec<u32>,
    pub normals: Option<Vec<f32>>,
    pub uvs: Option<Vec<f32>>,
}

/// Decompresses one zlib stream starting at `data[0]`; returns the output and the number of
/// input bytes it used. The output is charged to the load's memory budget as it grows.
fn inflate(data: &[u8]) -> Result<(Vec<u8>, usize), String> {
    let mut d = Decompress::new(true);
    let mut out: Vec<u8> = Vec::with_capacity(data.len().saturating_mul(3).min(1 << 26));
    let mut held =
        crate::limits::reserve(out.capacity() as u64, || "a serialized mesh".to_string())
            .map_err(|e| e.to_string())?;
    loop {
        if out.len() == out.capacity() {
            let more = out.capacity().max(1 << 16);
            if (out.len() + more) as u64 > MAX_SHAPE_BYTES {
                return Err("a shape decompresses to more than 4 GiB".into());
            }
            held.grow(more as u64, || "a serialized mesh".to_string())
                .map_err(|e| e.to_string())?;
            out.reserve(more);
        }
        let before = d.total_in() as usize;
        let st = d
            .decompress_vec(&data[before..], &mut out, FlushDecompress::None)
            .map_err(|e| format!("the compressed data is corrupt ({e})"))?;
        match st {
            Status::StreamEnd => break,
            Status::Ok | Status::BufError => {
                if d.total_in() as usize >= data.len() && out.len() < out.capacity() {
                    return Err("the compressed data ends early".into());
                }
            }
        }
    }
    held.keep();
    Ok((out, d.total_in() as usize))
}

struct Rd<'a> {
    b: &'a [u8],
    pos: usize,
}

impl Rd<'_> {
    fn take(&mut self, n: usize) -> Result<&[u8], String> {
        let end = self
            .pos
            .checked_add(n)
            .filter(|&e| e <= self.b.len())
            .ok_or("the shape's data is truncated")?;
        let s = &self.b[self.pos..end];
        self.pos = end;
        Ok(s)
    }
    fn u32(&mut self) -> Result<u32, String> {
        Ok(u32::from_le_bytes(
            self.take(4)?.try_into().unwrap_or([0; 4]),
        ))
    }
    fn u64(&mut self) -> Result<u64, String> {
        Ok(u64::from_le_bytes(
            self.take(8)?.try_into().unwrap_or([0; 8]),
        ))
    }
    fn floats(&mut self, n: usize, double: bool) -> Result<Vec<f32>, String> {
        let size = if double { 8 } else { 4 };
        let bytes = self.take(n.checked_mul(size).ok_or("the shape is too large")?)?;
        Ok(if double {
            bytes
                .chunks_exact(8)
                .map(|c| f64::from_le_bytes(c.try_into().unwrap_or([0; 8])) as f32)
                .collect()
        } else {
            bytes
                .chunks_exact(4)
                .map(|c| f32::from_le_bytes(c.try_into().unwrap_or([0; 4])))
                .collect()
        })
    }
}

/// Reads shape `index` of a `.serialized` file.
pub fn read(data: &[u8], index: usize) -> Result<SerializedMesh, String> {
    let mut pos = 0usize;
    let mut i = 0usize;
    loop {
        if data.len() < pos + 4 {
            return Err(format!("shape_index {index}: the file holds {i} shape(s)"));
        }
        let header = u16::from_le_bytes([data[pos], data[pos + 1]]);
        let version = u16::from_le_bytes([data[pos + 2], data[pos + 3]]);
        if header != HEADER {
            if i > 0 {
                return Err(format!("shape_index {index}: the file holds {i} shape(s)"));
            }
            return Err("not a Mitsuba serialized mesh (no 0x041C header)".into());
        }
        if !(version == 3 || version == 4) {
            return Err(format!(
                "serialized format version {version} is not supported (3 or 4)"
            ));
        }
        if i < index {
            // Skip this shape: inflate to find where its stream ends. Its output is dropped.
            let (_, used) = inflate(&data[pos + 4..])?;
            pos += 4 + used;
            i += 1;
            continue;
        }
        let (raw, _) = inflate(&data[pos + 4..])?;
        return parse_shape(&raw, version);
    }
}

fn parse_shape(raw: &[u8], version: u16) -> Result<SerializedMesh, String> {
    let mut r = Rd { b: raw, pos: 0 };
    let flags = r.u32()?;
    if version == 4 {
        let rest = &raw[r.pos..];
        let nul = rest
            .iter()
            .position(|&b| b == 0)
            .ok_or("the shape's name is not terminated")?;
        r.pos += nul + 1;
    }
    let nv = r.u64()?;
    let nt = r.u64()?;
    let too_big = |n: u64, per: u64| n.checked_mul(per).is_none_or(|b| b > raw.len() as u64);
    let double = flags & DOUBLE != 0;
    let fsize = if double { 8 } else { 4 };
    if too_big(nv, 3 * fsize) || too_big(nt, 12) {
        return Err(format!(
            "the shape claims {nv} vertices and {nt} triangles, more than its data holds"
        ));
    }
    let (nv, nt) = (nv as usize, nt as usize);
    let positions = r.floats(nv * 3, double)?;
    let normals = if flags & HAS_NORMALS != 0 {
        Some(r.floats(nv * 3, double)?)
    } else {
        None
    };
    let uvs = if flags & HAS_TEXCOORDS != 0 {
        Some(r.floats(nv * 2, double)?)
    } else {
        None
    };
    if flags & HAS_COLORS != 0 {
        r.floats(nv * 3, double)?;
    }
    let wide = nv as u64 > u64::from(u32::MAX);
    let mut indices = Vec::with_capacity(nt * 3);
    for _ in 0..nt * 3 {
        let v = if wide { r.u64()? } else { u64::from(r.u32()?) };
        if v >= nv as u64 {
            return Err(format!(
                "a triangle references vertex {v} but the shape has {nv}"
            ));
        }
        indices.push(v as u32);
    }
    Ok(SerializedMesh {
        positions,
        indices,
        normals,
        uvs,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use flate2::{Compression, write::ZlibEncoder};
    use std::io::Write;

    fn shape(version: u16, flags: u32, pos: &[f32], uv: &[f32], idx: &[u32]) -> Vec<u8> {
        let mut raw = flags.to_le_bytes().to_vec();
        if version == 4 {
            raw.extend_from_slice(b"name\0");
        }
        raw.extend_from_slice(&((pos.len() / 3) as u64).to_le_bytes());
        raw.extend_from_slice(&((idx.len() / 3) as u64).to_le_bytes());
        for v in pos.iter().chain(uv) {
            raw.extend_from_slice(&v.to_le_bytes());
        }
        for i in idx {
            raw.extend_from_slice(&i.to_le_bytes());
        }
        let mut z = ZlibEncoder::new(Vec::new(), Compression::default());
        z.write_all(&raw).unwrap();
        let mut out = HEADER.to_le_bytes().to_vec();
        out.extend_from_slice(&version.to_le_bytes());
        out.extend(z.finish().unwrap());
        out
    }

    #[test]
    fn reads_the_indexed_shape_of_a_sequence() {
        let tri = [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0];
        let mut file = shape(4, 0x1000, &tri, &[], &[0, 1, 2]);
        let second = [5.0, 0.0, 0.0, 6.0, 0.0, 0.0, 5.0, 1.0, 0.0];
        file.extend(shape(
            4,
            0x1000 | HAS_TEXCOORDS,
            &second,
            &[0.0, 0.0, 1.0, 0.0, 0.0, 1.0],
            &[0, 2, 1],
        ));
        let m = read(&file, 1).unwrap();
        assert_eq!(m.positions[0], 5.0);
        assert_eq!(m.indices, vec![0, 2, 1]);
        assert_eq!(m.uvs.unwrap().len(), 6);
        assert_eq!(read(&file, 0).unwrap().positions[3], 1.0);
        assert!(read(&file, 2).unwrap_err().contains("holds 2"));
        // An index out of range and a truncated stream are errors, not panics.
        let bad = shape(3, 0x1000, &tri, &[], &[0, 1, 3]);
        assert!(read(&bad, 0).is_err());
        assert!(read(&file[..file.len() / 2], 1).is_err());
    }
}
