//! Small numeric toolbox shared by every stage: re-exported vector types, orthonormal frames and the
//! floating-point error bounds used for robust ray spawning (Pharr, Jakob & Humphreys, *PBRT* 3rd ed.
//! §3.9 "Managing rounding error").

pub use glam::{Mat3, Mat4, Vec2, Vec3, Vec4};

pub const PI: f32 = std::f32::consts::PI;
pub const INV_PI: f32 = std::f32::consts::FRAC_1_PI;

/// Half of the machine epsilon: the bound on the relative error of one rounded f32 operation.
pub const MACHINE_EPSILON: f32 = f32::EPSILON * 0.5;

/// γ(n) = nε / (1 − nε): bound on the relative error accumulated by `n` f32 operations (PBRT eq. 3.8).
#[inline]
pub fn gamma(n: i32) -> f32 {
    let ne = n as f32 * MACHINE_EPSILON;
    ne / (1.0 - ne)
}

/// The next representable f32 above `v` (PBRT §3.9.1).
#[inline]
pub fn next_float_up(v: f32) -> f32 {
    if v.is_infinite() && v > 0.0 {
        return v;
    }
    let v = if v == -0.0 { 0.0 } else { v };
    let bits = v.to_bits();
    let bits = if v >= 0.0 { bits + 1 } else { bits - 1 };
    f32::from_bits(bits)
}

/// The next representable f32 below `v`.
#[inline]
pub fn next_float_down(v: f32) -> f32 {
    if v.is_infinite() && v < 0.0 {
        return v;
    }
    let v = if v == 0.0 { -0.0 } else { v };
    let bits = v.to_bits();
    let bits = if v > 0.0 { bits - 1 } else { bits + 1 };
    f32::from_bits(bits)
}

/// Moves a surface point `p` whose absolute error is bounded by `p_error` off the surface with normal `n`,
/// to the side of direction `w`, far enough that a ray leaving it cannot re-hit the same surface
/// (PBRT eq. 3.18 and `OffsetRayOrigin`). The offset scales with the point's magnitude, so results do
/// not depend on the scene's scale as a fixed epsilon would.
#[inline]
pub fn offset_ray_origin(p: Vec3, p_error: Vec3, n: Vec3, w: Vec3) -> Vec3 {
    let d = n.abs().dot(p_error);
    let mut offset = n * d;
    if w.dot(n) < 0.0 {
        offset = -offset;
    }
    let po = p + offset;
    away_by_one_ulp3(po, offset)
}

/// [`away_by_one_ulp`] on the three components at once. On x86_64 it is the same integer and
/// compare operations on the lanes of one SSE2 register (SSE2 is part of the x86_64 baseline, so
/// no runtime feature detection is needed). Callgrind, 64², 16 spp: the scalar form's branches
/// and selects were ~25 instructions per component, and a shadow ray spawns two offset points
/// (`Ray::spawn_to`, ~200 instructions per call, 4.7 % of the Cornell box's instructions); with
/// this step the Cornell box takes 1.3 % fewer instructions per sample, textured 1.3 %, veach
/// 0.7 %, and the signs of the offsets no longer feed branches. The result is bit-identical to
/// the scalar form (unit test below, special values included).
#[inline]
fn away_by_one_ulp3(v: Vec3, dir: Vec3) -> Vec3 {
    #[cfg(target_arch = "x86_64")]
    // SAFETY: the SSE and SSE2 intrinsics need only those CPU features, which every x86_64
    // CPU has (the target's baseline); they touch no memory. `unsafe` because Rust asks it of
    // `#[target_feature]` functions called outside a function that lists the feature; the
    // reason to use them is measured above.
    unsafe {
        use std::arch::x86_64::*;
        let vf = _mm_setr_ps(v.x, v.y, v.z, 0.0);
        let df = _mm_setr_ps(dir.x, dir.y, dir.z, 0.0);
        let zero = _mm_setzero_ps();
        let vb = _mm_castps_si128(vf);
        let db = _mm_castps_si128(df);
        // Lanes left as they are: dir == ±0, or v infinite or NaN (|bits| ≥ 0x7f800000).
        let abs_v = _mm_and_si128(vb, _mm_set1_epi32(0x7fff_ffff));
        let keep = _mm_or_si128(
            _mm_castps_si128(_mm_cmpeq_ps(df, zero)),
            _mm_cmpgt_epi32(abs_v, _mm_set1_epi32(0x7f7f_ffff)),
        );
        // ±0 becomes the zero on dir's side (its sign bit).
        let v_zero = _mm_castps_si128(_mm_cmpeq_ps(vf, zero));
        let dir_sign = _mm_and_si128(db, _mm_set1_epi32(i32::MIN));
        let v2 = _mm_or_si128(
            _mm_and_si128(v_zero, dir_sign),
            _mm_andnot_si128(v_zero, vb),
        );
        // `grows` (all ones, i.e. −1) when v2's sign agrees with dir < 0: the step is +1 then
        // and −1 otherwise, i.e. v2 − 1 − 2·grows.
        let v_neg = _mm_srai_epi32(v2, 31);
        let dir_neg = _mm_castps_si128(_mm_cmplt_ps(df, zero));
        let grows = _mm_cmpeq_epi32(v_neg, dir_neg);
        let stepped = _mm_sub_epi32(
            _mm_sub_epi32(v2, _mm_set1_epi32(1)),
            _mm_add_epi32(grows, grows),
        );
        let out = _mm_castsi128_ps(_mm_or_si128(
            _mm_and_si128(keep, vb),
            _mm_andnot_si128(keep, stepped),
        ));
        Vec3::new(
            _mm_cvtss_f32(out),
            _mm_cvtss_f32(_mm_shuffle_ps::<0b01_01_01_01>(out, out)),
            _mm_cvtss_f32(_mm_shuffle_ps::<0b10_10_10_10>(out, out)),
        )
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        Vec3::new(
            away_by_one_ulp(v.x, dir.x),
            away_by_one_ulp(v.y, dir.y),
            away_by_one_ulp(v.z, dir.z),
        )
    }
}

/// `next_float_up(v)` if `dir > 0`, `next_float_down(v)` if `dir < 0`, else `v`. The signs of the
/// offset are random from ray to ray, so this is written with selects rather than the branches of
/// the two functions (it runs three times per bounce and shadow ray). On x86_64 the renderer runs
/// [`away_by_one_ulp3`] instead, which the tests hold to this definition.
#[cfg(any(test, not(target_arch = "x86_64")))]
#[inline]
fn away_by_one_ulp(v: f32, dir: f32) -> f32 {
    if dir == 0.0 || !v.is_finite() {
        return v;
    }
    // ±0 becomes the zero on `dir`'s side, so the step leaves it towards `dir`.
    let v = if v == 0.0 { 0.0f32.copysign(dir) } else { v };
    let bits = v.to_bits();
    // Sign-magnitude: the step grows the magnitude (bits + 1) when it goes the way of v's sign.
    let grows = v.is_sign_negative() == (dir < 0.0);
    f32::from_bits(if grows { bits + 1 } else { bits - 1 })
}

/// An orthonormal basis whose `z` axis is a given unit normal. Shading happens in this local frame,
/// where cos θ is simply the `z` component.
#[derive(Clone, Copy, Debug)]
pub struct Frame {
    pub x: Vec3,
    pub y: Vec3,
    pub z: Vec3,
}

impl Frame {
    /// Builds a frame around unit vector `n` without branches on the sign of `n.z`
    /// (Duff et al. 2017, "Building an Orthonormal Basis, Revisited", JCGT 6(1)).
    #[inline]
    pub fn from_normal(n: Vec3) -> Frame {
        let sign = 1.0f32.copysign(n.z);
        let a = -1.0 / (sign + n.z);
        let b = n.x * n.y * a;
        let x = Vec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x);
        let y = Vec3::new(b, sign + n.y * n.y * a, -n.y);
        Frame { x, y, z: n }
    }

    /// Builds a frame from a normal and an approximate tangent (Gram–Schmidt), for normal mapping
    /// and anisotropic shading. Falls back to [`Frame::from_normal`] if the tangent is degenerate.
    #[inline]
    pub fn from_normal_tangent(n: Vec3, t: Vec3) -> Frame {
        let t = t - n * n.dot(t);
        let len2 = t.length_squared();
        if !(len2 > 1e-12) || !len2.is_finite() {
            return Frame::from_normal(n);
        }
        let x = t / len2.sqrt();
        Frame {
            x,
            y: n.cross(x),
            z: n,
        }
    }

    #[inline]
    pub fn to_local(&self, v: Vec3) -> Vec3 {
        Vec3::new(v.dot(self.x), v.dot(self.y), v.dot(self.z))
    }

    #[inline]
    pub fn to_world(&self, v: Vec3) -> Vec3 {
        self.x * v.x + self.y * v.y + self.z * v.z
    }
}

/// Relative luminance of a linear Rec.709 colour (used for light power and Russian roulette).
#[inline]
pub fn luminance(c: Vec3) -> f32 {
    0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z
}

/// Transforms a point by an affine 4×4 matrix.
#[inline]
pub fn transform_point(m: &Mat4, p: Vec3) -> Vec3 {
    m.transform_point3(p)
}

/// Transforms a normal by the inverse transpose of the matrix whose inverse is `inv`.
#[inline]
pub fn transform_normal(inv: &Mat4, n: Vec3) -> Vec3 {
    let m = Mat3::from_mat4(*inv).transpose();
    m * n
}

/// True when every element of the matrix is finite.
pub fn mat4_is_finite(m: &Mat4) -> bool {
    m.to_cols_array().iter().all(|v| v.is_finite())
}

/// The instruction sets the renderer's run-time dispatch chooses between. Three hot loops have
/// copies compiled with wider instruction sets, chosen when their structure is built: the
/// geometry BVH's traversal (`accel::bvh`, with AVX's eight-lane triangle pair test) and the light
/// BVH's descent (`light::bvh`) have an AVX2 copy (used at `avx2` and `avx512`: the eight-wide
/// BVH's slab test is one 256-bit operation per plane already); the wavefront path loop's
/// per-bounce sample numbers (`sampling::sampler::WaveDraw`, a loop across the wave's paths) have
/// an AVX2 copy and, at `avx512`, that copy with its 64-bit hashing in AVX-512 instructions.
/// Everything else is compiled for the target's baseline (SSE2 on x86-64, where a few SSE2
/// intrinsics are used without detection because every x86-64 CPU has them). Every copy computes
/// every float with the same IEEE operations (no FMA: it is not enabled, and Rust never contracts
/// `a * b + c`), so the image does not depend on the level (tests/simd.rs renders each level and
/// compares the bits).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum SimdLevel {
    /// The baseline code only.
    Portable,
    /// The AVX2 copies of the BVH traversal, the light BVH descent and the wave's sample numbers.
    Avx2,
    /// The AVX2 copies, with the wave's sample numbers hashed by AVX-512 (F, DQ, VL) on 256-bit
    /// registers.
    Avx512,
}

/// How the `TRAYECTO_SIMD` setting can be wrong.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum SimdError {
    /// A name that is not one of [`SimdLevel::ALL`].
    #[error(
        "TRAYECTO_SIMD={name:?} is not a SIMD level of this renderer (portable, avx2, avx512){hint}",
        name = .0,
        hint = simd_hint(.0)
    )]
    Unknown(String),
    /// A level the running CPU does not have.
    #[error("TRAYECTO_SIMD={level} asks for code this CPU does not have", level = .0.name())]
    Unsupported(SimdLevel),
    /// `TRAYECTO_NO_AVX2` (the older switch, an alias of `TRAYECTO_SIMD=portable`) set beside a
    /// `TRAYECTO_SIMD` that is not `portable`.
    #[error("TRAYECTO_NO_AVX2 is set (portable code) but TRAYECTO_SIMD={0}: set one of them")]
    Conflict(String),
}

fn simd_hint(name: &str) -> &'static str {
    match name.to_ascii_lowercase().as_str() {
        "avx-512" | "avx512f" | "avx512bw" | "avx512dq" => ": AVX-512 is `avx512`",
        "sse" | "sse2" | "sse4" | "sse4.1" | "sse4.2" => {
            ": `portable` is the SSE2 baseline on x86-64, and there is no SSE4 code"
        }
        _ => "",
    }
}

impl SimdLevel {
    /// Every level the code has, narrowest first.
    pub const ALL: [SimdLevel; 3] = [SimdLevel::Portable, SimdLevel::Avx2, SimdLevel::Avx512];

    /// The name `TRAYECTO_SIMD` takes.
    pub fn name(self) -> &'static str {
        match self {
            SimdLevel::Portable => "portable",
            SimdLevel::Avx2 => "avx2",
            SimdLevel::Avx512 => "avx512",
        }
    }

    /// The level called `name` (exactly one of [`Self::name`]'s).
    pub fn parse(name: &str) -> Result<SimdLevel, SimdError> {
        SimdLevel::ALL
            .into_iter()
            .find(|l| l.name() == name)
            .ok_or_else(|| SimdError::Unknown(name.to_string()))
    }

    /// Whether the running CPU can run this level's code.
    pub fn available(self) -> bool {
        match self {
            SimdLevel::Portable => true,
            #[cfg(target_arch = "x86_64")]
            SimdLevel::Avx2 => std::is_x86_feature_detected!("avx2"),
            #[cfg(target_arch = "x86_64")]
            SimdLevel::Avx512 => {
                std::is_x86_feature_detected!("avx2")
                    && std::is_x86_feature_detected!("avx512f")
                    && std::is_x86_feature_detected!("avx512dq")
                    && std::is_x86_feature_detected!("avx512vl")
            }
            #[cfg(not(target_arch = "x86_64"))]
            SimdLevel::Avx2 | SimdLevel::Avx512 => false,
        }
    }

    /// The widest level the running CPU has.
    pub fn best() -> SimdLevel {
        SimdLevel::ALL
            .into_iter()
            .rev()
            .find(|l| l.available())
            .unwrap_or(SimdLevel::Portable)
    }

    /// The level the settings `simd` (`TRAYECTO_SIMD`) and `no_avx2` (whether `TRAYECTO_NO_AVX2`
    /// is set) ask for: the named level if the CPU has it, [`Self::best`] when neither is set.
    pub fn from_settings(simd: Option<&str>, no_avx2: bool) -> Result<SimdLevel, SimdError> {
        let level = match (simd, no_avx2) {
            (None, false) => return Ok(SimdLevel::best()),
            (None, true) => SimdLevel::Portable,
            (Some(name), no_avx2) => {
                let level = SimdLevel::parse(name)?;
                if no_avx2 && level != SimdLevel::Portable {
                    return Err(SimdError::Conflict(name.to_string()));
                }
                level
            }
        };
        if level.available() {
            Ok(level)
        } else {
            Err(SimdError::Unsupported(level))
        }
    }
}

impl std::fmt::Display for SimdLevel {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// The SIMD level this process was asked for: `TRAYECTO_SIMD` (`portable`, `avx2`, `avx512`), or
/// `TRAYECTO_NO_AVX2` set (= `portable`), or else the widest the CPU has. Read once per process.
/// An unknown name or a level the CPU lacks is an error ([`SimdError`]); the render pipeline
/// refuses to start with it (`pipeline::RenderJob::check`).
pub fn simd_setting() -> Result<SimdLevel, SimdError> {
    static SETTING: std::sync::OnceLock<Result<SimdLevel, SimdError>> = std::sync::OnceLock::new();
    SETTING
        .get_or_init(|| {
            let simd = std::env::var("TRAYECTO_SIMD").ok();
            let no_avx2 = std::env::var_os("TRAYECTO_NO_AVX2").is_some();
            SimdLevel::from_settings(simd.as_deref(), no_avx2)
        })
        .clone()
}

/// The level every run-time dispatch site uses ([`simd_setting`]). A structure built outside the
/// pipeline (a library caller that skipped its check) with a bad setting gets the portable code,
/// the one level every CPU has, and a warning on stderr naming the setting, once per process.
pub fn simd_level() -> SimdLevel {
    match simd_setting() {
        Ok(level) => level,
        Err(e) => {
            static WARNED: std::sync::Once = std::sync::Once::new();
            WARNED.call_once(|| eprintln!("warning: {e}; using the portable code"));
            SimdLevel::Portable
        }
    }
}

/// Whether the structures with an AVX2-compiled copy of their hot loop (the geometry BVH's
/// traversal, the light BVH's descent) use it: [`simd_level`] is [`SimdLevel::Avx2`] or wider,
/// which implies the running CPU has AVX2 (false off x86-64). Asked once when such a structure is
/// built.
pub fn detect_avx2() -> bool {
    simd_level() >= SimdLevel::Avx2
}

/// ⌊x⌋ as an integer and as a float, bit for bit `(x.floor() as i64, x.floor())`. The target's
/// baseline x86-64 has no rounding instruction (SSE4.1), so `f32::floor` is a call into libm;
/// below 2²³ in magnitude truncation and one compare give the same value inline (the truncated
/// integer is exact there). Every float of magnitude ≥ 2²³ is an integer, its own floor, and so
/// are ±∞ and NaN (`floor` returns them unchanged), so no input needs the call: without it a
/// bilinear lookup (textures, environment maps) is a leaf function (the call's register saves
/// and spills were ~10 % of its instructions). −0 keeps its sign, as `floor(−0) = −0`.
#[inline]
pub fn floor_i64(x: f32) -> (i64, f32) {
    if !(x.abs() < 8_388_608.0) {
        return (x as i64, x);
    }
    let t = x as i32;
    let (i, f) = if (t as f32) > x {
        (t - 1, (t - 1) as f32)
    } else {
        (t, t as f32)
    };
    if f == 0.0 && x.is_sign_negative() {
        // x is −0 (a negative non-zero x above −1 floors to −1).
        return (0, x);
    }
    (i as i64, f)
}

/// M = T·R·S with S symmetric (pbrt-v4 `AnimatedTransform::Decompose`: the polar decomposition of
/// the upper 3×3 by iterating R ← (R + R⁻ᵀ)/2, then S = R⁻¹M).
pub fn decompose(m: Mat4) -> (Mat3, glam::Quat, Vec3) {
    let t = m.w_axis.truncate();
    let a = Mat3::from_mat4(m);
    let mut r = a;
    for _ in 0..100 {
        let next = (r + r.inverse().transpose()) * 0.5;
        let diff = (next - r)
            .to_cols_array()
            .iter()
            .map(|d| d.abs())
            .sum::<f32>();
        r = next;
        if diff < 1e-6 {
            break;
        }
    }
    if r.determinant() < 0.0 {
        r *= -1.0;
    }
    let q = glam::Quat::from_mat3(&r).normalize();
    let s = r.inverse() * a;
    (s, q, t)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `TRAYECTO_SIMD` and its alias: each level by its name (or an error naming what the CPU
    /// lacks), unknown names refused with the name in the message (AVX-512's other spellings with
    /// a hint), the alias alone is
    /// the portable code, and the alias beside another level is refused rather than either won.
    #[test]
    fn simd_setting_names_levels_and_refuses_the_rest() {
        assert_eq!(SimdLevel::from_settings(None, false), Ok(SimdLevel::best()));
        assert_eq!(
            SimdLevel::from_settings(None, true),
            Ok(SimdLevel::Portable)
        );
        for level in SimdLevel::ALL {
            let got = SimdLevel::from_settings(Some(level.name()), false);
            if level.available() {
                assert_eq!(got, Ok(level));
            } else {
                assert_eq!(got, Err(SimdError::Unsupported(level)));
            }
        }
        assert_eq!(
            SimdLevel::from_settings(Some("portable"), true),
            Ok(SimdLevel::Portable)
        );
        assert_eq!(
            SimdLevel::from_settings(Some("avx2"), true),
            Err(SimdError::Conflict("avx2".into()))
        );
        for bad in ["avx-512", "sse2", "AVX2", "", "fast"] {
            let e = SimdLevel::from_settings(Some(bad), false).unwrap_err();
            assert_eq!(e, SimdError::Unknown(bad.into()));
            assert!(e.to_string().contains(&format!("{bad:?}")), "{e}");
        }
        let e = SimdError::Unknown("avx512f".into()).to_string();
        assert!(e.contains("AVX-512 is `avx512`"), "{e}");
    }

    /// `floor_i64` is bit for bit `floor` (value, sign of zero, integer) on a sweep of ordinary
    /// values and on the edges: ±0, halves, integers and their neighbours, 2²³ ± 1 ulp, huge,
    /// infinite, NaN, subnormal. Fails if the truncation path drops the −1 step for negative
    /// non-integers or turns −0 into +0.
    #[test]
    fn fast_floor_is_floor() {
        let mut xs: Vec<f32> = vec![
            0.0,
            -0.0,
            0.5,
            -0.5,
            1.0,
            -1.0,
            -1.0 + f32::EPSILON,
            1.0 - f32::EPSILON / 2.0,
            -(1.0 - f32::EPSILON / 2.0),
            8_388_607.5,
            -8_388_607.5,
            8_388_608.0,
            -8_388_608.0,
            f32::from_bits(8_388_608f32.to_bits() - 1),
            -f32::from_bits(8_388_608f32.to_bits() - 1),
            1e20,
            -1e20,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::NAN,
            f32::MIN_POSITIVE / 4.0,
            -f32::MIN_POSITIVE / 4.0,
        ];
        let mut h = 0x9e37_79b9u32;
        for _ in 0..100_000 {
            h ^= h << 13;
            h ^= h >> 17;
            h ^= h << 5;
            xs.push((h as f32 / u32::MAX as f32 - 0.5) * 8192.0);
        }
        for k in -300..300 {
            let x = k as f32;
            xs.extend([
                x,
                f32::from_bits(x.to_bits() + 1),
                f32::from_bits(x.to_bits().max(1) - 1),
            ]);
        }
        for x in xs {
            let (i, f) = floor_i64(x);
            let r = x.floor();
            assert_eq!(f.to_bits(), r.to_bits(), "floor({x:e})");
            assert_eq!(i, r as i64, "floor({x:e}) as i64");
        }
    }

    #[test]
    fn next_float_moves_one_ulp() {
        for v in [0.0f32, -0.0, 1.0, -1.0, 1e-30, -1e30, 123.456] {
            let up = next_float_up(v);
            let down = next_float_down(v);
            assert!(up > v, "{v}");
            assert!(down < v, "{v}");
        }
        assert_eq!(next_float_up(1.0), 1.0 + f32::EPSILON);
    }

    #[test]
    fn branch_free_ulp_step_matches_next_float() {
        let values = [
            0.0f32,
            -0.0,
            1.0,
            -1.0,
            1e-30,
            -1e-30,
            f32::MIN_POSITIVE,
            -f32::MIN_POSITIVE,
            1e-45,
            -1e-45,
            123.456,
            -1e30,
            f32::MAX,
            f32::MIN,
        ];
        for v in values {
            let same = |a: f32, b: f32| a.to_bits() == b.to_bits() || (a == 0.0 && b == 0.0);
            assert!(same(away_by_one_ulp(v, 0.5), next_float_up(v)), "{v} up");
            assert!(
                same(away_by_one_ulp(v, -2.0), next_float_down(v)),
                "{v} down"
            );
            assert_eq!(away_by_one_ulp(v, 0.0).to_bits(), v.to_bits(), "{v} still");
        }
        assert_eq!(away_by_one_ulp(f32::INFINITY, -1.0), f32::INFINITY);
    }

    /// The three-lane step is the scalar one bit for bit, for every pairing of special and
    /// ordinary values (zeros of both signs, subnormals, extremes, infinities, NaNs) with
    /// directions of both signs, zero and NaN, and for hashed random bit patterns.
    #[test]
    fn three_lane_ulp_step_is_the_scalar_one() {
        let specials = [
            0.0f32,
            -0.0,
            1.0,
            -1.0,
            1e-45,
            -1e-45,
            f32::MIN_POSITIVE,
            -f32::MIN_POSITIVE,
            123.456,
            -7.5e-20,
            f32::MAX,
            f32::MIN,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::NAN,
            -f32::NAN,
        ];
        let check = |v: Vec3, d: Vec3| {
            let got = away_by_one_ulp3(v, d);
            for (i, g) in got.to_array().into_iter().enumerate() {
                let want = away_by_one_ulp(v[i], d[i]);
                assert_eq!(
                    g.to_bits(),
                    want.to_bits(),
                    "lane {i} of {v:?} towards {d:?}"
                );
            }
        };
        for &a in &specials {
            for &b in &specials {
                for &c in &specials {
                    check(Vec3::new(a, b, c), Vec3::new(b, c, a));
                    check(Vec3::new(a, b, c), Vec3::new(-c, a, -b));
                }
            }
        }
        let mut h = 0x9E37_79B9_7F4A_7C15u64;
        for _ in 0..100_000 {
            let mut next = || {
                h = crate::sampling::rng::mix64(h.wrapping_add(0x9E37_79B9_7F4A_7C15));
                f32::from_bits(h as u32)
            };
            check(
                Vec3::new(next(), next(), next()),
                Vec3::new(next(), next(), next()),
            );
        }
    }

    #[test]
    fn frame_is_orthonormal_for_all_normals() {
        let normals = [
            Vec3::Z,
            -Vec3::Z,
            Vec3::X,
            Vec3::new(0.0, 0.0, -0.999_999),
            Vec3::new(1.0, 2.0, -3.0).normalize(),
        ];
        for n in normals {
            let n = n.normalize();
            let f = Frame::from_normal(n);
            assert!((f.x.length() - 1.0).abs() < 1e-5);
            assert!((f.y.length() - 1.0).abs() < 1e-5);
            assert!(f.x.dot(f.y).abs() < 1e-5);
            assert!(f.x.dot(n).abs() < 1e-5);
            assert!(f.y.dot(n).abs() < 1e-5);
            // Right-handed: x × y = z.
            assert!((f.x.cross(f.y) - n).length() < 1e-4);
            let v = Vec3::new(0.3, -0.4, 0.5);
            assert!((f.to_world(f.to_local(v)) - v).length() < 1e-5);
        }
    }

    #[test]
    fn offset_leaves_the_surface_on_the_requested_side() {
        let p = Vec3::new(1e5, 3.0, -2e4);
        let err = Vec3::splat(gamma(7)) * p.abs();
        let n = Vec3::Y;
        let up = offset_ray_origin(p, err, n, Vec3::Y);
        let down = offset_ray_origin(p, err, n, -Vec3::Y);
        assert!(up.y > p.y);
        assert!(down.y < p.y);
    }
}
