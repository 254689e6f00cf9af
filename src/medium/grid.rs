//! Density grids of heterogeneous media: a 3D array of densities over a box, looked up with
//! trilinear interpolation between voxel centres (the texture convention of Mitsuba 3's
//! `gridvolume` and pbrt-v4's `SampledGrid`: voxel (i, j, k) sits at ((i+½)/nx, (j+½)/ny, (k+½)/nz)
//! of the box; between the outermost voxel centres and the box faces the edge values are held,
//! as Mitsuba's default `clamp` wrap mode does; outside the box the density is 0).
//!
//! Two sources: Mitsuba's binary `.vol` file ([`read_vol`]) and pbrt-v4's `uniformgrid` medium
//! (its `density` array, `nx ny nz` and bounds `p0 p1` — the importer builds a
//! [`crate::scene::MediumDesc`] directly). Both store x fastest: index = (z·ny + y)·nx + x.

use crate::geometry::Ray;
use crate::math::{Mat4, Vec3};

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

/// A density grid placed in the world.
#[derive(Clone, Debug)]
pub struct DensityGrid {
    pub nx: usize,
    pub ny: usize,
    pub nz: usize,
    pub data: Vec<f32>,
    /// World → unit cube [0, 1]³ of the grid.
    world_to_unit: Mat4,
    /// The largest density: the majorant scale over the whole box.
    pub max_density: f32,
}

impl DensityGrid {
    /// `unit_to_world` maps the unit cube [0, 1]³ onto the grid's box in the world.
    pub fn new(
        nx: usize,
        ny: usize,
        nz: usize,
        data: Vec<f32>,
        unit_to_world: Mat4,
    ) -> Result<DensityGrid, GridError> {
        check_resolution(nx as i64, ny as i64, nz as i64)?;
        if data.len() != nx * ny * nz {
            return Err(GridError::Size {
                expected: (nx * ny * nz * 4) as u64,
                found: (data.len() * 4) as u64,
            });
        }
        if let Some((i, &v)) = data
            .iter()
            .enumerate()
            .find(|(_, v)| !(v.is_finite() && **v >= 0.0))
        {
            return Err(GridError::Value(i, v));
        }
        let det = unit_to_world.determinant();
        if !crate::math::mat4_is_finite(&unit_to_world) || !det.is_normal() {
            return Err(GridError::Transform);
        }
        let world_to_unit = unit_to_world.inverse();
        if !crate::math::mat4_is_finite(&world_to_unit) {
            return Err(GridError::Transform);
        }
        let max_density = data.iter().copied().fold(0.0f32, f32::max);
        Ok(DensityGrid {
            nx,
            ny,
            nz,
            data,
            world_to_unit,
            max_density,
        })
    }

    #[inline]
    fn at(&self, x: usize, y: usize, z: usize) -> f32 {
        self.data[(z * self.ny + y) * self.nx + x]
    }

    /// Density at world point `p` (0 outside the box).
    #[inline]
    pub fn density(&self, p: Vec3) -> f32 {
        let q = self.world_to_unit.transform_point3(p);
        if !(q.cmpge(Vec3::ZERO).all() && q.cmple(Vec3::ONE).all()) {
            return 0.0;
        }
        let coord = |v: f32, n: usize| -> (usize, usize, f32) {
            let x = (v * n as f32 - 0.5).clamp(0.0, (n - 1) as f32);
            let i0 = (x.floor() as usize).min(n - 1);
            let i1 = (i0 + 1).min(n - 1);
            (i0, i1, x - i0 as f32)
        };
        let (x0, x1, fx) = coord(q.x, self.nx);
        let (y0, y1, fy) = coord(q.y, self.ny);
        let (z0, z1, fz) = coord(q.z, self.nz);
        let lerp = |a: f32, b: f32, t: f32| a + (b - a) * t;
        let c00 = lerp(self.at(x0, y0, z0), self.at(x1, y0, z0), fx);
        let c10 = lerp(self.at(x0, y1, z0), self.at(x1, y1, z0), fx);
        let c01 = lerp(self.at(x0, y0, z1), self.at(x1, y0, z1), fx);
        let c11 = lerp(self.at(x0, y1, z1), self.at(x1, y1, z1), fx);
        lerp(lerp(c00, c10, fy), lerp(c01, c11, fy), fz)
    }

    /// The part of `ray` over `[0, t_max)` inside the grid's box, as a parameter interval.
    pub fn clip(&self, ray: &Ray, t_max: f32) -> Option<(f32, f32)> {
        let o = self.world_to_unit.transform_point3(ray.o);
        let d = self.world_to_unit.transform_vector3(ray.d);
        let (mut t0, mut t1) = (0.0f32, t_max);
        for a in 0..3 {
            let inv = 1.0 / d[a];
            let (mut ta, mut tb) = ((0.0 - o[a]) * inv, (1.0 - o[a]) * inv);
            if ta > tb {
                std::mem::swap(&mut ta, &mut tb);
            }
            if ta.is_nan() || tb.is_nan() {
                // Parallel to the slab: inside it or not.
                if o[a] < 0.0 || o[a] > 1.0 {
                    return None;
                }
                continue;
            }
            t0 = t0.max(ta);
            t1 = t1.min(tb);
            if t0 >= t1 {
                return None;
            }
        }
        Some((t0, t1))
    }
}

fn check_resolution(nx: i64, ny: i64, nz: i64) -> Result<(), GridError> {
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

/// The matrix mapping the unit cube onto the axis-aligned box [min, max].
pub fn box_to_world(min: Vec3, max: Vec3) -> Mat4 {
    Mat4::from_translation(min) * Mat4::from_scale(max - min)
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

    #[test]
    fn trilinear_lookup_hits_voxel_centres_and_is_zero_outside() {
        let v = sample_vol();
        let g = DensityGrid::new(
            v.nx,
            v.ny,
            v.nz,
            v.data.clone(),
            box_to_world(v.bbox_min, v.bbox_max),
        )
        .unwrap();
        let ext = v.bbox_max - v.bbox_min;
        for z in 0..2 {
            for y in 0..3 {
                for x in 0..2 {
                    let q = Vec3::new(
                        (x as f32 + 0.5) / 2.0,
                        (y as f32 + 0.5) / 3.0,
                        (z as f32 + 0.5) / 2.0,
                    );
                    let p = v.bbox_min + q * ext;
                    let want = v.data[(z * 3 + y) * 2 + x];
                    assert!((g.density(p) - want).abs() < 1e-5, "voxel {x},{y},{z}");
                }
            }
        }
        // Halfway between two x-neighbours: the mean.
        let p = v.bbox_min + Vec3::new(0.5, 0.5 / 3.0, 0.25) * ext;
        assert!((g.density(p) - 0.25).abs() < 1e-5);
        assert_eq!(g.density(Vec3::new(5.0, 1.0, 3.0)), 0.0);
        assert_eq!(g.max_density, 5.5);
        let r = Ray::new(Vec3::new(-3.0, 1.0, 3.0), Vec3::X);
        let (t0, t1) = g.clip(&r, f32::INFINITY).unwrap();
        assert!((t0 - 2.0).abs() < 1e-5 && (t1 - 4.0).abs() < 1e-5);
        assert!(g.clip(&r, 1.5).is_none());
        assert!(
            DensityGrid::new(1, 1, 1, vec![f32::NAN], Mat4::IDENTITY).is_err(),
            "NaN density"
        );
        assert!(DensityGrid::new(1, 1, 1, vec![1.0], Mat4::ZERO).is_err());
    }
}
