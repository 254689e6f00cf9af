//! Image textures: compact texel storage (8-bit sRGB or linear, 16-bit linear, f32), bilinear or
//! nearest lookup with glTF wrap modes and an optional `KHR_texture_transform`.
//!
//! Texels are stored as the file holds them and decoded at lookup: an 8-bit texel is 4 bytes
//! instead of a `Vec4`'s 16, so a model's textures take a quarter of the memory and the cache
//! lines a bilinear lookup touches hold four times as many texels. Decoding goes through exact
//! tables ([`SRGB8_TO_LINEAR`], [`UNORM8_TO_F32`]) holding the very values the loaders used to
//! compute at load (`srgb_to_linear(i / 255)` and `i / 255`), so every lookup is bit-identical to
//! the float storage it replaces.

use std::sync::LazyLock;

use crate::math::{Vec2, Vec4};

#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum WrapMode {
    #[default]
    Repeat,
    MirroredRepeat,
    ClampToEdge,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum FilterMode {
    Nearest,
    #[default]
    Bilinear,
}

/// `i / 255` for every 8-bit value: the linear (data) decoding, exactly as the `image` crate's
/// u8 → f32 conversion computes it (a division, not a multiplication by 1/255).
pub static UNORM8_TO_F32: LazyLock<[f32; 256]> =
    LazyLock::new(|| std::array::from_fn(|i| i as f32 / 255.0));

/// `i × (1/255)` for every 8-bit value: how the `image` crate expands grey (and some other)
/// layouts to float, which differs from `i / 255` by one float ulp for some codes.
pub static UNORM8_TO_F32_RECIP: LazyLock<[f32; 256]> =
    LazyLock::new(|| std::array::from_fn(|i| i as f32 * (1.0 / 255.0)));

/// `srgb_to_linear(i / 255)` for every 8-bit value: the sRGB decoding of colour textures.
pub static SRGB8_TO_LINEAR: LazyLock<[f32; 256]> =
    LazyLock::new(|| std::array::from_fn(|i| srgb_to_linear(i as f32 / 255.0)));

/// Texel storage, row-major, top row first (as images are stored). The variants are the forms a
/// texel takes in files; lookups decode to linear RGBA `Vec4`.
#[derive(Clone, Debug, PartialEq)]
pub enum Texels {
    /// 8-bit RGBA; RGB sRGB-encoded (decoded by [`SRGB8_TO_LINEAR`]), alpha linear.
    Srgb8(Vec<[u8; 4]>),
    /// 8-bit RGBA, every channel linear (normal, metallic-roughness, occlusion maps), decoded
    /// by [`UNORM8_TO_F32`].
    Unorm8(Vec<[u8; 4]>),
    /// 8-bit RGBA, every channel linear, decoded by [`UNORM8_TO_F32_RECIP`] (the loaders pick
    /// whichever table reproduces the `image` crate's float conversion of the file exactly).
    Unorm8Recip(Vec<[u8; 4]>),
    /// 16-bit RGBA, every channel linear (`v / 65535`, as the `image` crate converts).
    Unorm16(Vec<[u16; 4]>),
    /// Linear float RGBA: HDR images, 16-bit sRGB images (decoded at load) and computed textures.
    F32(Vec<Vec4>),
}

impl Default for Texels {
    fn default() -> Self {
        Texels::F32(Vec::new())
    }
}

impl From<Vec<Vec4>> for Texels {
    /// Float texels, stored 8-bit when that loses nothing (see [`Texels::compact`]).
    fn from(v: Vec<Vec4>) -> Self {
        Texels::compact(v)
    }
}

#[inline]
pub(crate) fn decode8(lut: &[f32; 256], alpha: &[f32; 256], p: [u8; 4]) -> Vec4 {
    Vec4::new(
        lut[p[0] as usize],
        lut[p[1] as usize],
        lut[p[2] as usize],
        alpha[p[3] as usize],
    )
}

#[inline]
pub(crate) fn decode16(p: [u16; 4]) -> Vec4 {
    // A per-lane IEEE division: the same value as the image crate's `v as f32 / 65535.0`.
    Vec4::new(p[0] as f32, p[1] as f32, p[2] as f32, p[3] as f32) / 65535.0
}

/// The 8-bit code whose table entry is exactly `v`, if there is one (tables are increasing).
fn exact_code(lut: &[f32; 256], v: f32) -> Option<u8> {
    let i = lut.partition_point(|&x| x < v);
    (i < 256 && lut[i] == v && v.to_bits() != (-0.0f32).to_bits()).then_some(i as u8)
}

impl Texels {
    /// Float texels in the most compact storage that decodes to exactly the same values: 8-bit
    /// sRGB when every colour channel is a [`SRGB8_TO_LINEAR`] entry and alpha a
    /// [`UNORM8_TO_F32`] entry, 8-bit linear when every channel is a [`UNORM8_TO_F32`] entry,
    /// else f32. Loaders that build float texels (packed metallic-roughness, baked pbrt
    /// textures) get compact storage this way without a change in any lookup.
    pub fn compact(v: Vec<Vec4>) -> Texels {
        let (srgb, unorm) = (&*SRGB8_TO_LINEAR, &*UNORM8_TO_F32);
        let encode = |lut: &[f32; 256]| -> Option<Vec<[u8; 4]>> {
            v.iter()
                .map(|t| {
                    Some([
                        exact_code(lut, t.x)?,
                        exact_code(lut, t.y)?,
                        exact_code(lut, t.z)?,
                        exact_code(unorm, t.w)?,
                    ])
                })
                .collect()
        };
        if v.is_empty() {
            return Texels::F32(v);
        }
        if let Some(b) = encode(unorm) {
            return Texels::Unorm8(b);
        }
        if let Some(b) = encode(srgb) {
            return Texels::Srgb8(b);
        }
        Texels::F32(v)
    }

    pub fn len(&self) -> usize {
        match self {
            Texels::Srgb8(v) | Texels::Unorm8(v) | Texels::Unorm8Recip(v) => v.len(),
            Texels::Unorm16(v) => v.len(),
            Texels::F32(v) => v.len(),
        }
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Bytes per texel of this storage (for memory accounting).
    pub fn bytes_per_texel(&self) -> usize {
        match self {
            Texels::Srgb8(_) | Texels::Unorm8(_) | Texels::Unorm8Recip(_) => 4,
            Texels::Unorm16(_) => 8,
            Texels::F32(_) => 16,
        }
    }

    /// Name of the storage kind, for reports.
    pub fn kind(&self) -> &'static str {
        match self {
            Texels::Srgb8(_) => "srgb8",
            Texels::Unorm8(_) => "unorm8",
            Texels::Unorm8Recip(_) => "unorm8-recip",
            Texels::Unorm16(_) => "unorm16",
            Texels::F32(_) => "f32",
        }
    }

    /// Texel `i`, decoded to linear RGBA. Panics when `i` is out of range, as slice indexing does.
    #[inline]
    pub fn get(&self, i: usize) -> Vec4 {
        match self {
            Texels::Srgb8(v) => decode8(&SRGB8_TO_LINEAR, &UNORM8_TO_F32, v[i]),
            Texels::Unorm8(v) => decode8(&UNORM8_TO_F32, &UNORM8_TO_F32, v[i]),
            Texels::Unorm8Recip(v) => decode8(&UNORM8_TO_F32_RECIP, &UNORM8_TO_F32_RECIP, v[i]),
            Texels::Unorm16(v) => decode16(v[i]),
            Texels::F32(v) => v[i],
        }
    }

    /// Texel `i` decoded, or `None` out of range.
    #[inline]
    pub fn try_get(&self, i: usize) -> Option<Vec4> {
        (i < self.len()).then(|| self.get(i))
    }

    /// Every texel, decoded, in storage order.
    pub fn iter(&self) -> impl Iterator<Item = Vec4> + '_ {
        (0..self.len()).map(move |i| self.get(i))
    }

    /// Every texel decoded to float.
    pub fn to_f32(&self) -> Vec<Vec4> {
        self.iter().collect()
    }
}

/// A decoded image. Colour textures are sRGB-decoded to linear at lookup (see [`Texels`]).
#[derive(Clone, Debug, PartialEq)]
pub struct Texture {
    pub name: String,
    pub width: u32,
    pub height: u32,
    pub texels: Texels,
    pub wrap_s: WrapMode,
    pub wrap_t: WrapMode,
    pub filter: FilterMode,
}

/// UV transform (KHR_texture_transform): uv' = T · R · S · uv.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct UvTransform {
    pub offset: Vec2,
    pub rotation: f32,
    pub scale: Vec2,
}

impl UvTransform {
    #[inline]
    pub fn apply(&self, uv: Vec2) -> Vec2 {
        let s = uv * self.scale;
        let (sin, cos) = self.rotation.sin_cos();
        // glTF's rotation is counter-clockwise in UV space with v pointing down.
        Vec2::new(cos * s.x + sin * s.y, -sin * s.x + cos * s.y) + self.offset
    }
}

/// A material's use of a texture.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TextureRef {
    pub texture: usize,
    /// Which texture-coordinate set (0 or 1).
    pub texcoord: u32,
    pub transform: Option<UvTransform>,
}

impl TextureRef {
    pub fn new(texture: usize) -> TextureRef {
        TextureRef {
            texture,
            texcoord: 0,
            transform: None,
        }
    }
}

/// sRGB electro-optical transfer function (IEC 61966-2-1).
#[inline]
pub fn srgb_to_linear(c: f32) -> f32 {
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

#[inline]
pub fn linear_to_srgb(c: f32) -> f32 {
    if c <= 0.0031308 {
        c * 12.92
    } else {
        1.055 * c.powf(1.0 / 2.4) - 0.055
    }
}

impl Texture {
    /// An image texture as decoded: row-major texels, top row first, repeating and bilinear
    /// (glTF's defaults; loaders set other wrap or filter modes afterwards).
    /// Float texels are stored 8-bit when that is exact ([`Texels::compact`]).
    pub fn image(name: &str, width: u32, height: u32, texels: Vec<Vec4>) -> Texture {
        Texture::with_texels(name, width, height, Texels::compact(texels))
    }

    /// An image texture with texels already in their storage form (repeating, bilinear).
    pub fn with_texels(name: &str, width: u32, height: u32, texels: Texels) -> Texture {
        Texture {
            name: name.to_string(),
            width,
            height,
            texels,
            wrap_s: WrapMode::Repeat,
            wrap_t: WrapMode::Repeat,
            filter: FilterMode::Bilinear,
        }
    }

    /// A constant 1×1 texture.
    pub fn constant(name: &str, v: Vec4) -> Texture {
        Texture {
            name: name.to_string(),
            width: 1,
            height: 1,
            texels: Texels::F32(vec![v]),
            wrap_s: WrapMode::Repeat,
            wrap_t: WrapMode::Repeat,
            filter: FilterMode::Nearest,
        }
    }

    #[inline]
    fn wrap(i: i64, n: u32, mode: WrapMode) -> usize {
        let n = n as i64;
        let v = match mode {
            WrapMode::Repeat => i.rem_euclid(n),
            WrapMode::ClampToEdge => i.clamp(0, n - 1),
            WrapMode::MirroredRepeat => {
                let period = 2 * n;
                let m = i.rem_euclid(period);
                if m < n { m } else { period - 1 - m }
            }
        };
        v as usize
    }

    #[inline]
    fn index(&self, x: i64, y: i64) -> usize {
        let xi = Self::wrap(x, self.width, self.wrap_s);
        let yi = Self::wrap(y, self.height, self.wrap_t);
        yi * self.width as usize + xi
    }

    /// Looks up (u, v) with v = 0 at the top row (glTF convention).
    #[inline]
    pub fn lookup(&self, uv: Vec2) -> Vec4 {
        if !uv.is_finite() {
            return self.texels.get(0);
        }
        let x = uv.x * self.width as f32;
        let y = uv.y * self.height as f32;
        match self.filter {
            FilterMode::Nearest => self
                .texels
                .get(self.index(x.floor() as i64, y.floor() as i64)),
            FilterMode::Bilinear => {
                let (fx, fy) = (x - 0.5, y - 0.5);
                let (x0, y0) = (fx.floor(), fy.floor());
                let (tx, ty) = (fx - x0, fy - y0);
                let (x0, y0) = (x0 as i64, y0 as i64);
                let i = [
                    self.index(x0, y0),
                    self.index(x0 + 1, y0),
                    self.index(x0, y0 + 1),
                    self.index(x0 + 1, y0 + 1),
                ];
                // One match per lookup, not per texel: the storage kind picks the decoder once.
                let [t00, t10, t01, t11] = match &self.texels {
                    Texels::Srgb8(v) => {
                        let (c, a) = (&*SRGB8_TO_LINEAR, &*UNORM8_TO_F32);
                        i.map(|i| decode8(c, a, v[i]))
                    }
                    Texels::Unorm8(v) => {
                        let a = &*UNORM8_TO_F32;
                        i.map(|i| decode8(a, a, v[i]))
                    }
                    Texels::Unorm8Recip(v) => {
                        let a = &*UNORM8_TO_F32_RECIP;
                        i.map(|i| decode8(a, a, v[i]))
                    }
                    Texels::Unorm16(v) => i.map(|i| decode16(v[i])),
                    Texels::F32(v) => i.map(|i| v[i]),
                };
                let a = t00 * (1.0 - tx) + t10 * tx;
                let b = t01 * (1.0 - tx) + t11 * tx;
                a * (1.0 - ty) + b * ty
            }
        }
    }

    /// Average texel value (for light power estimates).
    pub fn average(&self) -> Vec4 {
        let sum: Vec4 = self.texels.iter().sum();
        sum / self.texels.len().max(1) as f32
    }

    /// Replaces every texel by `f(texel)`; the result is stored as float.
    pub fn map_texels(&mut self, f: impl Fn(Vec4) -> Vec4) {
        self.texels = Texels::F32(self.texels.iter().map(f).collect());
    }

    /// Bytes the texels take.
    pub fn texel_bytes(&self) -> usize {
        self.texels.len() * self.texels.bytes_per_texel()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn checker() -> Texture {
        Texture {
            name: "c".into(),
            width: 2,
            height: 2,
            texels: Texels::F32(vec![Vec4::ZERO, Vec4::ONE, Vec4::ONE, Vec4::ZERO]),
            wrap_s: WrapMode::Repeat,
            wrap_t: WrapMode::Repeat,
            filter: FilterMode::Nearest,
        }
    }

    #[test]
    fn nearest_and_wrap_modes() {
        let mut t = checker();
        assert_eq!(t.lookup(Vec2::new(0.25, 0.25)), Vec4::ZERO);
        assert_eq!(t.lookup(Vec2::new(0.75, 0.25)), Vec4::ONE);
        assert_eq!(t.lookup(Vec2::new(1.25, 0.25)), Vec4::ZERO);
        t.wrap_s = WrapMode::ClampToEdge;
        assert_eq!(t.lookup(Vec2::new(1.25, 0.25)), Vec4::ONE);
        t.wrap_s = WrapMode::MirroredRepeat;
        assert_eq!(t.lookup(Vec2::new(1.25, 0.25)), Vec4::ONE);
        assert_eq!(t.lookup(Vec2::new(-0.25, 0.25)), Vec4::ZERO);
    }

    #[test]
    fn bilinear_interpolates_between_texel_centres() {
        let mut t = checker();
        t.filter = FilterMode::Bilinear;
        t.wrap_s = WrapMode::ClampToEdge;
        t.wrap_t = WrapMode::ClampToEdge;
        let mid = t.lookup(Vec2::new(0.5, 0.25));
        assert!((mid.x - 0.5).abs() < 1e-6);
        assert_eq!(t.lookup(Vec2::new(0.25, 0.25)), Vec4::ZERO);
    }

    /// Float texels are stored 8-bit only when every value decodes back exactly; anything else
    /// (one value between codes, −0, NaN, HDR) keeps float. Fails if `compact` rounds.
    #[test]
    fn compact_is_exact_or_float() {
        let unorm: Vec<Vec4> = (0..256)
            .map(|i| Vec4::new(i as f32 / 255.0, 1.0, 0.0, (255 - i) as f32 / 255.0))
            .collect();
        let t = Texels::compact(unorm.clone());
        assert_eq!(t.kind(), "unorm8");
        assert_eq!(t.to_f32(), unorm);
        let srgb: Vec<Vec4> = (0..256)
            .map(|i| {
                let c = srgb_to_linear(i as f32 / 255.0);
                Vec4::new(c, 1.0, c, (i / 2) as f32 / 255.0)
            })
            .collect();
        let t = Texels::compact(srgb.clone());
        assert_eq!(t.kind(), "srgb8");
        assert_eq!(t.to_f32(), srgb);
        for odd in [0.3f32, -0.0, f32::NAN, 2.0, -1.0 / 255.0] {
            let mut v = unorm.clone();
            v[17].y = odd;
            let t = Texels::compact(v);
            assert_eq!(t.kind(), "f32", "{odd}");
            assert_eq!(t.get(17).y.to_bits(), odd.to_bits());
        }
    }

    #[test]
    fn srgb_round_trip() {
        for c in [0.0f32, 0.001, 0.04, 0.5, 1.0] {
            assert!((linear_to_srgb(srgb_to_linear(c)) - c).abs() < 1e-5);
        }
        assert!((srgb_to_linear(0.5) - 0.214).abs() < 1e-3);
    }

    #[test]
    fn uv_transform_matches_gltf_spec_example() {
        // Offset only.
        let t = UvTransform {
            offset: Vec2::new(0.5, 0.0),
            rotation: 0.0,
            scale: Vec2::ONE,
        };
        assert_eq!(t.apply(Vec2::new(0.1, 0.2)), Vec2::new(0.6, 0.2));
        // Rotation by 90° maps u to -v in glTF's convention.
        let r = UvTransform {
            offset: Vec2::ZERO,
            rotation: std::f32::consts::FRAC_PI_2,
            scale: Vec2::ONE,
        };
        let p = r.apply(Vec2::new(1.0, 0.0));
        assert!((p - Vec2::new(0.0, -1.0)).length() < 1e-6);
    }
}
