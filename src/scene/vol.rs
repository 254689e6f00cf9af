//! Mitsuba's binary `.vol` density grid, as the loaders read it (reading a file is the loader's
//! side; `medium::grid` compiles the grid it describes), and the errors of grids in general,
//! which `medium` reports too.

use crate::math::Vec3;

#[derive(Debug, thiserror::Error, PartialEq)]
pub enum GridError {
    #[error("not a Mitsuba .vol file (no 'VOL' header)")]
    NotVol,
    #[error(".vol version {0} is not supported (only version 3)")]
    Version(u8),
    #[error(".vol encoding {0} is not supported (only 1 = float32)")]
    Encoding(i32),
    #[error("the grid has {0} channels; a density grid needs 1")]
    Channels(i32),
    #[error("invalid grid resolution {0} x {1} x {2}")]
    Resolution(i64, i64, i64),
    #[error(
        "the file is truncated or has trailing data: {expected} bytes of voxels expected, {found} found"
    )]
    Size { expected: u64, found: u64 },
    #[error("the grid's bounding box is empty or not finite")]
    Bounds,
    #[error("voxel {0} is negative or not finite ({1})")]
    Value(usize, f32),
    #[error("the grid transform is not invertible or not finite")]
    Transform,
}

/// Largest grid accepted (voxels): 512³, 512 MiB of f32. A hostile header cannot make the loader
/// allocate more.
pub const MAX_VOXELS: u64 = 512 * 512 * 512;

pub(crate) fn check_resolution(nx: i64, ny: i64, nz: i64) -> Result<(), GridError> {
    let ok = nx > 0
        && ny > 0
        && nz > 0
        && (nx as u64)
            .checked_mul(ny as u64)
            .and_then(|v| v.checked_mul(nz as u64))
            .is_some_and(|v| v <= MAX_VOXELS);
    if ok {
        Ok(())
    } else {
        Err(GridError::Resolution(nx, ny, nz))
    }
}

/// A grid read from a Mitsuba `.vol` file: resolution, the voxels and the box it spans (in the
/// file's own space; Mitsuba places it in the world with the volume's `to_world`, identity here).
#[derive(Clone, Debug, PartialEq)]
pub struct VolFile {
    pub nx: usize,
    pub ny: usize,
    pub nz: usize,
    pub data: Vec<f32>,
    pub bbox_min: Vec3,
    pub bbox_max: Vec3,
}

/// Parses Mitsuba's binary `.vol` grid (the format of Mitsuba 0.6 to 3, `gridvolume`): the bytes
/// 'V' 'O' 'L', version byte 3, then little-endian i32 encoding (1 = float32), i32 nx, ny, nz,
/// i32 channel count, six f32 for the bounding box (min xyz, max xyz), then nx·ny·nz·channels f32
/// with x fastest and the channels interleaved. Only single-channel float32 grids are accepted.
pub fn read_vol(bytes: &[u8]) -> Result<VolFile, GridError> {
    const HEADER: usize = 48;
    if bytes.len() < HEADER || &bytes[0..3] != b"VOL" {
        return Err(GridError::NotVol);
    }
    if bytes[3] != 3 {
        return Err(GridError::Version(bytes[3]));
    }
    let i32_at = |o: usize| i32::from_le_bytes(bytes[o..o + 4].try_into().unwrap());
    let f32_at = |o: usize| f32::from_le_bytes(bytes[o..o + 4].try_into().unwrap());
    let encoding = i32_at(4);
    if encoding != 1 {
        return Err(GridError::Encoding(encoding));
    }
    let (nx, ny, nz) = (i32_at(8) as i64, i32_at(12) as i64, i32_at(16) as i64);
    check_resolution(nx, ny, nz)?;
    let channels = i32_at(20);
    if channels != 1 {
        return Err(GridError::Channels(channels));
    }
    let bbox_min = Vec3::new(f32_at(24), f32_at(28), f32_at(32));
    let bbox_max = Vec3::new(f32_at(36), f32_at(40), f32_at(44));
    if !(bbox_min.is_finite() && bbox_max.is_finite() && bbox_min.cmplt(bbox_max).all()) {
        return Err(GridError::Bounds);
    }
    let n = (nx * ny * nz) as u64;
    let found = (bytes.len() - HEADER) as u64;
    if found != n * 4 {
        return Err(GridError::Size {
            expected: n * 4,
            found,
        });
    }
    let data: Vec<f32> = bytes[HEADER..]
        .chunks_exact(4)
        .map(|c| f32::from_le_bytes(c.try_into().unwrap()))
        .collect();
    Ok(VolFile {
        nx: nx as usize,
        ny: ny as usize,
        nz: nz as usize,
        data,
        bbox_min,
        bbox_max,
    })
}

/// Writes a single-channel float32 `.vol` file (used by tests and the reference script's twin).
pub fn write_vol(v: &VolFile) -> Vec<u8> {
    let mut out = Vec::with_capacity(48 + v.data.len() * 4);
    out.extend_from_slice(b"VOL");
    out.push(3);
    for i in [1i32, v.nx as i32, v.ny as i32, v.nz as i32, 1] {
        out.extend_from_slice(&i.to_le_bytes());
    }
    for f in [
        v.bbox_min.x,
        v.bbox_min.y,
        v.bbox_min.z,
        v.bbox_max.x,
        v.bbox_max.y,
        v.bbox_max.z,
    ] {
        out.extend_from_slice(&f.to_le_bytes());
    }
    for f in &v.data {
        out.extend_from_slice(&f.to_le_bytes());
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample_vol() -> VolFile {
        VolFile {
            nx: 2,
            ny: 3,
            nz: 2,
            data: (0..12).map(|i| i as f32 * 0.5).collect(),
            bbox_min: Vec3::new(-1.0, 0.0, 2.0),
            bbox_max: Vec3::new(1.0, 3.0, 4.0),
        }
    }

    #[test]
    fn vol_round_trips_and_rejects_hostile_headers() {
        let v = sample_vol();
        let bytes = write_vol(&v);
        assert_eq!(read_vol(&bytes).unwrap(), v);
        assert_eq!(read_vol(b"VOX").unwrap_err(), GridError::NotVol);
        let mut b = bytes.clone();
        b[3] = 2;
        assert_eq!(read_vol(&b).unwrap_err(), GridError::Version(2));
        let mut b = bytes.clone();
        b.truncate(b.len() - 1);
        assert!(matches!(read_vol(&b), Err(GridError::Size { .. })));
        // A huge resolution must be refused before any allocation.
        let mut b = bytes.clone();
        b[8..12].copy_from_slice(&i32::MAX.to_le_bytes());
        assert!(matches!(read_vol(&b), Err(GridError::Resolution(..))));
        let mut b = bytes.clone();
        b[8..12].copy_from_slice(&(-4i32).to_le_bytes());
        assert!(matches!(read_vol(&b), Err(GridError::Resolution(..))));
        let mut b = bytes.clone();
        b[20..24].copy_from_slice(&3i32.to_le_bytes());
        assert_eq!(read_vol(&b).unwrap_err(), GridError::Channels(3));
        let mut b = bytes;
        b[24..28].copy_from_slice(&f32::NAN.to_le_bytes());
        assert_eq!(read_vol(&b).unwrap_err(), GridError::Bounds);
        // Every truncation of a valid file is an error, never a panic.
        let bytes = write_vol(&v);
        for n in 0..bytes.len() {
            assert!(read_vol(&bytes[..n]).is_err());
        }
    }
}
