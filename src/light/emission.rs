//! What an emissive texture emits over one triangle, read once when the lights are built.
//!
//! A model whose emissive texture lights up a few decals (ToyCar: flames and a number on a car
//! body of 88 837 triangles that all share the emissive material) used to make every triangle a
//! light with the texture's mean radiance as its power: almost every light sample landed on a
//! black texel and was wasted, and the light set was 20–50× larger than the emitting surface.
//! Here each triangle's UV footprint is read from the texture: triangles whose footprint is
//! black are not lights at all (their emission is exactly zero wherever a ray hits them or a
//! light sample lands), and the others get the mean of their footprint as their power.

use crate::material::texture::{FilterMode, Texture, TextureRef, WrapMode};
use crate::math::{Vec2, Vec3};

/// Footprints larger than this many texels are not read: the triangle keeps the texture's mean.
const MAX_FOOTPRINT_TEXELS: i64 = 1 << 14;

/// The mean RGB of the texels that texture lookups anywhere on a triangle with texture
/// coordinates `uvs` (before the reference's transform) can touch, or `None` if that set is too
/// large to read or the coordinates are not finite. The set is conservative: the texel box of
/// the transformed triangle, widened by one texel on every side for bilinear filtering and for
/// rounding in the interpolated coordinates, folded into the texture by its wrap modes. So a
/// zero mean means every lookup on the triangle returns exactly zero.
pub fn footprint_mean(texture: &Texture, tref: &TextureRef, uvs: [Vec2; 3]) -> Option<Vec3> {
    let uvs = uvs.map(|uv| match &tref.transform {
        Some(t) => t.apply(uv),
        None => uv,
    });
    if !uvs.iter().all(|uv| uv.is_finite()) || texture.texels.is_empty() {
        return None;
    }
    let (w, h) = (texture.width as i64, texture.height as i64);
    let lo = uvs[0].min(uvs[1]).min(uvs[2]);
    let hi = uvs[0].max(uvs[1]).max(uvs[2]);
    // Nearest reads floor(u·w); bilinear floor(u·w − ½) and the next texel: both inside
    // [floor(u·w) − 1, floor(u·w) + 1].
    let margin = match texture.filter {
        FilterMode::Nearest | FilterMode::Bilinear => 1,
    };
    let span = |a: f32, b: f32, n: i64| -> Option<(i64, i64)> {
        let (a, b) = ((a as f64 * n as f64).floor(), (b as f64 * n as f64).floor());
        if !(a.abs() < 1e15 && b.abs() < 1e15) {
            return None;
        }
        Some((a as i64 - margin, b as i64 + margin))
    };
    let (x0, x1) = span(lo.x, hi.x, w)?;
    let (y0, y1) = span(lo.y, hi.y, h)?;
    let xs = fold(x0, x1, w, texture.wrap_s);
    let ys = fold(y0, y1, h, texture.wrap_t);
    let count: i64 = xs.iter().map(|(a, b)| b - a + 1).sum::<i64>()
        * ys.iter().map(|(a, b)| b - a + 1).sum::<i64>();
    if count > MAX_FOOTPRINT_TEXELS {
        return None;
    }
    let mut sum = [0.0f64; 3];
    for &(ya, yb) in &ys {
        for y in ya..=yb {
            for &(xa, xb) in &xs {
                for x in xa as usize..=xb as usize {
                    let t = texture.texel(x, y as usize);
                    // Negative texels would let a sum hide a non-zero one: count magnitudes.
                    sum[0] += t.x.abs() as f64;
                    sum[1] += t.y.abs() as f64;
                    sum[2] += t.z.abs() as f64;
                }
            }
        }
    }
    let n = count.max(1) as f64;
    Some(Vec3::new(
        (sum[0] / n) as f32,
        (sum[1] / n) as f32,
        (sum[2] / n) as f32,
    ))
}

/// The texel indices in [0, n) that indices `a..=b` reach under `mode`, as at most two inclusive
/// intervals (a superset for mirrored spans that cross a mirror).
fn fold(a: i64, b: i64, n: i64, mode: WrapMode) -> Vec<(i64, i64)> {
    let full = vec![(0, n - 1)];
    match mode {
        WrapMode::ClampToEdge => vec![(a.clamp(0, n - 1), b.clamp(0, n - 1))],
        WrapMode::Repeat => {
            if b - a + 1 >= n {
                return full;
            }
            let s = a.rem_euclid(n);
            let e = s + (b - a);
            if e < n {
                vec![(s, e)]
            } else {
                vec![(s, n - 1), (0, e - n)]
            }
        }
        WrapMode::MirroredRepeat => {
            if b - a + 1 >= n || a.div_euclid(n) != b.div_euclid(n) {
                return full;
            }
            let m = |i: i64| {
                let k = i.rem_euclid(2 * n);
                if k < n { k } else { 2 * n - 1 - k }
            };
            let (s, e) = (m(a), m(b));
            vec![(s.min(e), s.max(e))]
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Vec4;

    fn texture(w: u32, h: u32, lit: &[(u32, u32)], filter: FilterMode, wrap: WrapMode) -> Texture {
        let mut texels = vec![Vec4::new(0.0, 0.0, 0.0, 1.0); (w * h) as usize];
        for &(x, y) in lit {
            texels[(y * w + x) as usize] = Vec4::new(2.0, 1.0, 0.5, 1.0);
        }
        Texture {
            name: "e".into(),
            width: w,
            height: h,
            texels: texels.into(),
            wrap_s: wrap,
            wrap_t: wrap,
            filter,
            mipmap: true,
            mips: Vec::new(),
            procedural: None,
            layout: Default::default(),
        }
    }

    /// The claim the light set rests on: where the footprint mean is zero, every lookup on the
    /// triangle is zero. Checked by brute force over random triangles, points inside them (and
    /// slightly outside, as interpolation rounding gives), every filter and wrap mode and a UV
    /// transform; and the footprint does see the lit texel when a lookup does.
    #[test]
    fn zero_footprint_means_zero_lookups() {
        let mut rng = crate::sampling::rng::Pcg32::new(7, 3);
        let mut zero_seen = 0;
        let mut lit_seen = 0;
        for filter in [FilterMode::Nearest, FilterMode::Bilinear] {
            for wrap in [
                WrapMode::Repeat,
                WrapMode::MirroredRepeat,
                WrapMode::ClampToEdge,
            ] {
                let tex = texture(16, 8, &[(3, 2), (15, 7)], filter, wrap);
                for k in 0..3000 {
                    let tref = TextureRef {
                        texture: 0,
                        texcoord: 0,
                        transform: (k % 3 == 0).then_some(crate::material::texture::UvTransform {
                            offset: Vec2::new(0.3, -0.7),
                            rotation: 0.4,
                            scale: Vec2::new(1.5, 0.8),
                        }),
                    };
                    let c = Vec2::new(rng.next_f32() * 3.0 - 1.0, rng.next_f32() * 3.0 - 1.0);
                    let size = 0.02 + 0.2 * rng.next_f32();
                    let uvs = [0, 1, 2]
                        .map(|_| c + Vec2::new(rng.next_f32() - 0.5, rng.next_f32() - 0.5) * size);
                    let mean = footprint_mean(&tex, &tref, uvs).unwrap();
                    let mut any = false;
                    for _ in 0..200 {
                        let (mut b1, mut b2) = (rng.next_f32(), rng.next_f32());
                        if b1 + b2 > 1.0 {
                            (b1, b2) = (1.0 - b1, 1.0 - b2);
                        }
                        let (b1, b2) = (b1 * 1.0001 - 5e-5, b2 * 1.0001 - 5e-5);
                        let uv = uvs[0] * (1.0 - b1 - b2) + uvs[1] * b1 + uvs[2] * b2;
                        let uv = tref.transform.map_or(uv, |t| t.apply(uv));
                        any |= tex.lookup(uv).truncate() != Vec3::ZERO;
                    }
                    if mean == Vec3::ZERO {
                        zero_seen += 1;
                        assert!(
                            !any,
                            "{filter:?} {wrap:?}: zero footprint, lit lookup {uvs:?}"
                        );
                    } else if any {
                        lit_seen += 1;
                    }
                }
            }
        }
        assert!(
            zero_seen > 1000 && lit_seen > 1000,
            "{zero_seen} {lit_seen}"
        );
    }

    #[test]
    fn footprint_mean_of_one_lit_texel() {
        let tex = texture(8, 8, &[(4, 4)], FilterMode::Nearest, WrapMode::ClampToEdge);
        // A triangle inside texel (4, 4): the box is 3×3 texels around it.
        let uvs = [
            Vec2::new(4.2 / 8.0, 4.2 / 8.0),
            Vec2::new(4.8 / 8.0, 4.2 / 8.0),
            Vec2::new(4.5 / 8.0, 4.8 / 8.0),
        ];
        let m = footprint_mean(&tex, &TextureRef::new(0), uvs).unwrap();
        assert!(
            (m - Vec3::new(2.0, 1.0, 0.5) / 9.0).abs().max_element() < 1e-6,
            "{m}"
        );
        // Non-finite coordinates and huge footprints are not read.
        let bad = [Vec2::new(f32::NAN, 0.0), Vec2::ZERO, Vec2::ONE];
        assert!(footprint_mean(&tex, &TextureRef::new(0), bad).is_none());
        let big = texture(1024, 1024, &[], FilterMode::Nearest, WrapMode::Repeat);
        let whole = [Vec2::ZERO, Vec2::new(0.9, 0.0), Vec2::new(0.0, 0.9)];
        assert!(footprint_mean(&big, &TextureRef::new(0), whole).is_none());
    }
}
