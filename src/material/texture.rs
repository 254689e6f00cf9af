//! Image textures: compact texel storage (8-bit sRGB or linear, 16-bit linear, f32), bilinear or
//! nearest lookup with glTF wrap modes and an optional `KHR_texture_transform`.
//!
//! Texels are stored as the file holds them and decoded at lookup: an 8-bit texel is 4 bytes
//! instead of a `Vec4`'s 16, so a model's textures take a quarter of the memory and the cache
//! lines a bilinear lookup touches hold four times as many texels. Decoding goes through exact
//! tables ([`SRGB8_TO_LINEAR`], [`UNORM8_TO_F32`]) holding the very values the loaders used to
//! compute at load (`srgb_to_linear(i / 255)` and `i / 255`), so every lookup is bit-identical to
//! the float storage it replaces.

use std::cell::Cell;
use std::sync::LazyLock;

use crate::math::{Vec2, Vec4, floor_i64};

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

/// Whether textures are filtered over the pixel footprint (`--texture-filter`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum TextureFilter {
    /// Each texture's own nearest or bilinear lookup at the hit's uv, as before filtering
    /// existed: no pyramids are built.
    #[default]
    None,
    /// MIP pyramids and trilinear lookups driven by ray footprints.
    Trilinear,
}

impl TextureFilter {
    /// The name `--texture-filter` takes (what `FromStr` parses back).
    pub fn name(self) -> &'static str {
        match self {
            TextureFilter::None => "none",
            TextureFilter::Trilinear => "trilinear",
        }
    }

    /// Every filter, for front ends that list the choices.
    pub const ALL: [TextureFilter; 2] = [TextureFilter::None, TextureFilter::Trilinear];
}

impl std::str::FromStr for TextureFilter {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "none" => Ok(TextureFilter::None),
            "trilinear" => Ok(TextureFilter::Trilinear),
            _ => Err(format!(
                "unknown texture filter '{s}' (expected none or trilinear)"
            )),
        }
    }
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
    /// to [`UNORM8_TO_F32`]'s values (computed per lane at lookup, `decode_unorm8`).
    Unorm8(Vec<[u8; 4]>),
    /// 8-bit RGBA, every channel linear, decoded to [`UNORM8_TO_F32_RECIP`]'s values (the loaders pick
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

/// An 8-bit linear texel decoded by arithmetic instead of [`UNORM8_TO_F32`]: `i as f32 / 255`
/// per channel, the very operation that built the table (integers below 2²⁴ convert exactly and
/// IEEE division rounds each lane alike, so the bits are the table's; the test
/// `unorm8_arithmetic_is_the_table` checks all 256 codes). Four lanes in one division instead of
/// four table loads assembled into a vector: ToyCar's normal and metallic-roughness lookups.
#[inline(always)]
pub(crate) fn decode_unorm8(p: [u8; 4]) -> Vec4 {
    Vec4::new(p[0] as f32, p[1] as f32, p[2] as f32, p[3] as f32) / 255.0
}

/// [`decode_unorm8`] for [`UNORM8_TO_F32_RECIP`]: `i as f32 × (1/255)` per lane, as the table.
#[inline(always)]
pub(crate) fn decode_unorm8_recip(p: [u8; 4]) -> Vec4 {
    Vec4::new(p[0] as f32, p[1] as f32, p[2] as f32, p[3] as f32) * (1.0 / 255.0)
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
            Texels::Unorm8(v) => decode_unorm8(v[i]),
            Texels::Unorm8Recip(v) => decode_unorm8_recip(v[i]),
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

    /// These texels (row-major, `w` × `h`) in 4 × 4 tiles ([`TexelLayout`]).
    pub fn tiled(&self, w: u32, h: u32) -> (Texels, TexelLayout) {
        let (w, h) = (w as usize, h as usize);
        match self {
            Texels::Srgb8(v) => {
                let (v, l) = TexelLayout::tile(v, w, h);
                (Texels::Srgb8(v), l)
            }
            Texels::Unorm8(v) => {
                let (v, l) = TexelLayout::tile(v, w, h);
                (Texels::Unorm8(v), l)
            }
            Texels::Unorm8Recip(v) => {
                let (v, l) = TexelLayout::tile(v, w, h);
                (Texels::Unorm8Recip(v), l)
            }
            Texels::Unorm16(v) => {
                let (v, l) = TexelLayout::tile(v, w, h);
                (Texels::Unorm16(v), l)
            }
            Texels::F32(v) => {
                let (v, l) = TexelLayout::tile(v, w, h);
                (Texels::F32(v), l)
            }
        }
    }

    /// `v` (linear RGBA) stored in this storage's kind, rounded to its nearest codes (for MIP
    /// levels: an 8-bit image's pyramid stays 8-bit). The 8-bit linear kinds both store as
    /// [`Texels::Unorm8`].
    pub fn encode_like(&self, v: &[Vec4]) -> Texels {
        let q8 = |x: f32| (x.clamp(0.0, 1.0) * 255.0).round() as u8;
        let q16 = |x: f32| (x.clamp(0.0, 1.0) * 65535.0).round() as u16;
        match self {
            Texels::Srgb8(_) => Texels::Srgb8(
                v.iter()
                    .map(|t| {
                        let s = |c: f32| q8(linear_to_srgb(c.clamp(0.0, 1.0)));
                        [s(t.x), s(t.y), s(t.z), q8(t.w)]
                    })
                    .collect(),
            ),
            Texels::Unorm8(_) | Texels::Unorm8Recip(_) => {
                Texels::Unorm8(v.iter().map(|t| t.to_array().map(q8)).collect())
            }
            Texels::Unorm16(_) => {
                Texels::Unorm16(v.iter().map(|t| t.to_array().map(q16)).collect())
            }
            Texels::F32(_) => Texels::F32(v.to_vec()),
        }
    }
}

/// `src` resampled to `n` values by an exact box: output `i` is the mean of the piecewise-
/// constant input over [i·r, (i+1)·r), r = len/n, each input texel weighted by its overlap. The
/// weights of every input texel sum to 1/r over the outputs, so the mean is kept.
fn box_resample(src: &[Vec4], n: usize) -> Vec<Vec4> {
    let m = src.len();
    if n == m {
        return src.to_vec();
    }
    let r = m as f64 / n as f64;
    (0..n)
        .map(|i| {
            let (a, b) = (i as f64 * r, (i + 1) as f64 * r);
            let mut acc = Vec4::ZERO;
            for (j, &v) in src
                .iter()
                .enumerate()
                .take((b.ceil() as usize).min(m))
                .skip(a.floor() as usize)
            {
                let overlap = (b.min(j as f64 + 1.0) - a.max(j as f64)).max(0.0);
                acc += v * (overlap / r) as f32;
            }
            acc
        })
        .collect()
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
    /// Whether minified lookups may read the MIP pyramid (glTF: a sampler whose `minFilter` is
    /// `NEAREST` or `LINEAR` asks for no MIP maps; pbrt-v4 always filters through its pyramid).
    pub mipmap: bool,
    /// Levels 1, 2, … of the MIP pyramid (level 0 is `texels`), built by [`Texture::build_mips`]
    /// when texture filtering is on; empty otherwise, and then every lookup is the plain one.
    pub mips: Vec<MipLevel>,
    /// A pbrt-v4 procedural texture evaluated per hit ([`super::eval::sample_texture`]); its
    /// `texels` then hold one texel, its mean, which plain lookups and light-power estimates use.
    pub procedural: Option<Box<super::procedural::Procedural>>,
    /// Where each level-0 texel lives in `texels`: row-major as loaded; tiled once the world is
    /// compiled ([`Texture::tile`]). Read texels by position through [`Texture::texel`].
    pub layout: TexelLayout,
}

/// One level of a MIP pyramid: half the size of the level below (rounded down, at least 1),
/// each texel the area-weighted box average of the texels it covers.
#[derive(Clone, Debug, PartialEq)]
pub struct MipLevel {
    pub width: u32,
    pub height: u32,
    pub texels: Texels,
    /// Where each texel of this level lives in `texels`.
    pub layout: TexelLayout,
}

/// Bytes per cache line: the unit a tiled level's tiles are aligned to.
const CACHE_LINE: usize = 64;

/// Side of the square tiles of [`Texture::tile`], as a power of two: 4 × 4 texels, so an 8-bit
/// tile is 64 bytes, one cache line.
pub const TILE_LOG2: u32 = 2;
const TILE: usize = 1 << TILE_LOG2;
const TILE_MASK: usize = TILE - 1;

/// How a level's texels are ordered in its [`Texels`] storage.
///
/// Row-major (the default: images as loaded) puts texel (x, y) at `y·w + x`, so the two rows of
/// a bilinear footprint are `4·w` bytes apart (4 KiB for a 1024-wide 8-bit image): two cache
/// lines, and two pages, per lookup. Tiled stores the image as 4 × 4 tiles, each contiguous,
/// tiles row by row, the last column and row of tiles padded: texel (x, y) is at
/// `base + (⌊y/4⌋·tiles_x + ⌊x/4⌋)·16 + (y mod 4)·4 + x mod 4`, so most footprints fall in one
/// tile, one cache line (the blocked texture layouts of texture caches: Hakura & Gupta 1997,
/// "The Design and Analysis of a Cache Architecture for Texture Mapping"). `base` pads the
/// start so that tiles begin on a cache line. Only addresses change: the texels read, and so
/// every lookup's bits, are the same in both layouts.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub struct TexelLayout {
    /// Tiled (else row-major).
    pub tiled: bool,
    /// Tiled: index of texel (0, 0).
    pub base: usize,
    /// Tiled: texels per row of tiles, `16 · tiles_x`.
    pub tile_row: usize,
}

impl TexelLayout {
    /// The part of texel (x, ·)'s index that depends on its column (tiled).
    #[inline(always)]
    fn tiled_col(x: usize) -> usize {
        ((x & !TILE_MASK) << TILE_LOG2) | (x & TILE_MASK)
    }

    /// The part of texel (·, y)'s index that depends on its row (tiled).
    #[inline(always)]
    fn tiled_row(self, y: usize) -> usize {
        self.base + (y >> TILE_LOG2) * self.tile_row + ((y & TILE_MASK) << TILE_LOG2)
    }

    /// Storage index of texel (x, y), 0 ≤ x < `width`, of a level laid out this way.
    #[inline(always)]
    pub fn index(self, width: u32, x: usize, y: usize) -> usize {
        if self.tiled {
            self.tiled_row(y) + Self::tiled_col(x)
        } else {
            y * width as usize + x
        }
    }

    /// Storage indices of texels (xa, ya), (xb, ya), (xa, yb), (xb, yb): a bilinear footprint,
    /// with one test of the layout (it is the same for every lookup of a texture, so the branch
    /// predicts; a branch-free form with variable shifts cost ~20 instructions per lookup).
    #[inline(always)]
    fn quad(self, width: u32, xa: usize, xb: usize, ya: usize, yb: usize) -> [usize; 4] {
        let ((ra, rb), (ca, cb)) = if self.tiled {
            (
                (self.tiled_row(ya), self.tiled_row(yb)),
                (Self::tiled_col(xa), Self::tiled_col(xb)),
            )
        } else {
            ((ya * width as usize, yb * width as usize), (xa, xb))
        };
        [ra + ca, ra + cb, rb + ca, rb + cb]
    }

    /// `v` (row-major, `w` × `h`) reordered into 4 × 4 tiles, with the layout that addresses
    /// the result. Padding (the start, for alignment, and the partial tiles at the right and
    /// bottom edges) repeats the nearest edge texel; lookups never read it.
    fn tile<T: Copy>(v: &[T], w: usize, h: usize) -> (Vec<T>, TexelLayout) {
        assert_eq!(v.len(), w * h, "texel count of a {w}x{h} level");
        let t = TILE;
        let (tiles_x, tiles_y) = (w.div_ceil(t), h.div_ceil(t));
        let size = std::mem::size_of::<T>();
        let mut out = Vec::with_capacity(tiles_x * tiles_y * t * t + CACHE_LINE / size);
        // The allocation's offset within a cache line, rounded up to whole texels (the vector
        // never reallocates: its capacity covers the padding). A clone loses the alignment, not
        // the correctness: `base` is an index, not an address.
        let misalign = out.as_ptr() as usize % CACHE_LINE;
        let base = ((CACHE_LINE - misalign) % CACHE_LINE).div_ceil(size);
        out.resize(base, v[0]);
        for ty in 0..tiles_y {
            for tx in 0..tiles_x {
                for r in 0..t {
                    let row = &v[(ty * t + r).min(h - 1) * w..][..w];
                    match row.get(tx * t..tx * t + t) {
                        Some(run) => out.extend_from_slice(run),
                        None => out.extend((0..t).map(|c| row[(tx * t + c).min(w - 1)])),
                    }
                }
            }
        }
        let layout = TexelLayout {
            tiled: true,
            base,
            tile_row: tiles_x * t * t,
        };
        (out, layout)
    }
}

/// The largest derivative of a UV footprint, (∂u/∂x, ∂v/∂x, ∂u/∂y, ∂v/∂y) per pixel, below which
/// a lookup is a plain magnified one.
const NO_FOOTPRINT: f32 = 0.0;

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
        // Most transforms only scale and offset: skip the sine and cosine of +0, which are
        // exactly (0, 1) (the bit test leaves −0, whose sine is −0, to `sin_cos`).
        let (sin, cos) = if self.rotation.to_bits() == 0 {
            (0.0, 1.0)
        } else {
            self.rotation.sin_cos()
        };
        // glTF's rotation is counter-clockwise in UV space with v pointing down.
        Vec2::new(cos * s.x + sin * s.y, -sin * s.x + cos * s.y) + self.offset
    }
}

/// The texel addresses (relative to the level's tile start) and bilinear weights of one
/// level-0 lookup, with what they depend on: the uv's bits, the level's size, wrap modes and
/// layout. Kept by [`Texture::lookup_shared`] so that the next lookup at the same hit of a
/// texture with the same key skips the addressing. [`SharedFootprint::NONE`] matches nothing.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SharedFootprint {
    uv: [u32; 2],
    width: u32,
    height: u32,
    wrap_s: WrapMode,
    wrap_t: WrapMode,
    tiled: bool,
    tile_row: usize,
    quad: [usize; 4],
    tx: f32,
    ty: f32,
}

impl SharedFootprint {
    /// No footprint yet (width 0: no texture has it).
    pub const NONE: SharedFootprint = SharedFootprint {
        uv: [0; 2],
        width: 0,
        height: 0,
        wrap_s: WrapMode::Repeat,
        wrap_t: WrapMode::Repeat,
        tiled: false,
        tile_row: 0,
        quad: [0; 4],
        tx: 0.0,
        ty: 0.0,
    };

    /// Whether a lookup keyed `other` reads the same texel positions with the same weights.
    #[inline(always)]
    fn same_positions(&self, other: &SharedFootprint) -> bool {
        self.uv == other.uv
            && self.width == other.width
            && self.height == other.height
            && self.wrap_s == other.wrap_s
            && self.wrap_t == other.wrap_t
            && self.tiled == other.tiled
            && self.tile_row == other.tile_row
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

/// The four texels of a bilinear lookup, decoded by `f`. Spelled out: `[T; 4]::map` compiled to
/// an out-of-line `try_map` call per lookup (84 instructions of ToyCar's ~350 per lookup).
#[inline(always)]
fn fetch4(i: [usize; 4], f: impl Fn(usize) -> Vec4) -> [Vec4; 4] {
    [f(i[0]), f(i[1]), f(i[2]), f(i[3])]
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
            mipmap: true,
            mips: Vec::new(),
            procedural: None,
            layout: TexelLayout::default(),
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
            mipmap: false,
            mips: Vec::new(),
            procedural: None,
            layout: TexelLayout::default(),
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

    /// The wrapped indices of texel `i` and of its neighbour `i + 1`: what [`Texture::wrap`]
    /// gives for each, with one division instead of two (a bilinear lookup's two columns or two
    /// rows). `i` inside `[0, n − 1)`, the common case, needs none. Always inlined: as a call it
    /// cost ToyCar ~20 instructions per lookup.
    #[inline(always)]
    fn wrap_pair(i: i64, n: u32, mode: WrapMode) -> (usize, usize) {
        let n64 = n as i64;
        if i >= 0 && i < n64 - 1 {
            return (i as usize, i as usize + 1);
        }
        match mode {
            // (i + 1) mod n is i mod n + 1, or 0 where that reaches n.
            WrapMode::Repeat => {
                let a = i.rem_euclid(n64);
                let b = if a + 1 == n64 { 0 } else { a + 1 };
                (a as usize, b as usize)
            }
            _ => (Self::wrap(i, n, mode), Self::wrap(i + 1, n, mode)),
        }
    }

    #[inline]
    fn index(&self, x: i64, y: i64) -> usize {
        self.index_in(self.width, self.height, self.layout, x, y)
    }

    /// Storage index of texel (x, y) of a `width` × `height` level laid out as `layout`, after
    /// the wrap modes.
    #[inline]
    fn index_in(&self, width: u32, height: u32, layout: TexelLayout, x: i64, y: i64) -> usize {
        let xi = Self::wrap(x, width, self.wrap_s);
        let yi = Self::wrap(y, height, self.wrap_t);
        layout.index(width, xi, yi)
    }

    /// Level-0 texel (x, y), 0 ≤ x < width, 0 ≤ y < height (top row 0), whatever the layout.
    #[inline]
    pub fn texel(&self, x: usize, y: usize) -> Vec4 {
        debug_assert!(x < self.width as usize && y < self.height as usize);
        self.texels.get(self.layout.index(self.width, x, y))
    }

    /// Every level-0 texel, row by row from the top (the order images are stored in).
    pub fn texels_row_major(&self) -> impl Iterator<Item = Vec4> + '_ {
        let (w, h) = (self.width as usize, self.height as usize);
        (0..h).flat_map(move |y| (0..w).map(move |x| self.texel(x, y)))
    }

    /// Reorders level 0 and every MIP level into 4 × 4 tiles ([`TexelLayout`]): the same texels at new indices, so lookups return the same bits and a
    /// bilinear footprint mostly reads one cache line instead of two rows `4·width` bytes apart.
    /// Done once the world is compiled (after MIP building and light estimates). 1 × 1 levels
    /// and already tiled textures stay as they are.
    pub fn tile(&mut self) {
        if self.layout.tiled || self.texels.len() <= 1 {
            return;
        }
        (self.texels, self.layout) = self.texels.tiled(self.width, self.height);
        for m in &mut self.mips {
            if m.texels.len() > 1 {
                (m.texels, m.layout) = m.texels.tiled(m.width, m.height);
            }
        }
    }

    /// Looks up (u, v) with v = 0 at the top row (glTF convention). Always inlined (into
    /// [`Texture::lookup_filtered`]): the call cost ToyCar ~2 instructions per lookup
    /// (callgrind: the two functions 9.05 M -> 8.63 M instructions for 210 k lookups).
    #[inline(always)]
    pub fn lookup(&self, uv: Vec2) -> Vec4 {
        if !uv.is_finite() {
            return self.texels.get(0);
        }
        let x = uv.x * self.width as f32;
        let y = uv.y * self.height as f32;
        match self.filter {
            FilterMode::Nearest => self.texels.get(self.index(floor_i64(x).0, floor_i64(y).0)),
            FilterMode::Bilinear => {
                self.bilinear(self.width, self.height, &self.texels, self.layout, x, y)
            }
        }
    }

    /// Bilinear interpolation between the texel centres of a `width` × `height` level at
    /// (x, y) in that level's texel units.
    #[inline]
    fn bilinear(
        &self,
        width: u32,
        height: u32,
        texels: &Texels,
        layout: TexelLayout,
        x: f32,
        y: f32,
    ) -> Vec4 {
        let (quad, tx, ty) = self.bilinear_address(width, height, layout, x, y);
        Self::blend(texels, quad, tx, ty)
    }

    /// Where a bilinear lookup at (x, y) (texel units of a `width` × `height` level laid out
    /// as `layout`) reads: the storage indices of its four texels and the weights (tx, ty).
    #[inline(always)]
    fn bilinear_address(
        &self,
        width: u32,
        height: u32,
        layout: TexelLayout,
        x: f32,
        y: f32,
    ) -> ([usize; 4], f32, f32) {
        let (fx, fy) = (x - 0.5, y - 0.5);
        let ((x0, x0f), (y0, y0f)) = (floor_i64(fx), floor_i64(fy));
        let (tx, ty) = (fx - x0f, fy - y0f);
        // Each axis is wrapped once for both of its texels (ToyCar: the eight separate wraps, a
        // 64-bit division each for repeating textures, were a quarter of a lookup's
        // instructions).
        let (xa, xb) = Self::wrap_pair(x0, width, self.wrap_s);
        let (ya, yb) = Self::wrap_pair(y0, height, self.wrap_t);
        (layout.quad(width, xa, xb, ya, yb), tx, ty)
    }

    /// The bilinear blend of the four texels at storage indices `i` with weights (tx, ty).
    #[inline(always)]
    fn blend(texels: &Texels, i: [usize; 4], tx: f32, ty: f32) -> Vec4 {
        // One match per lookup, not per texel: the storage kind picks the decoder once.
        let [t00, t10, t01, t11] = match texels {
            Texels::Srgb8(v) => {
                let (c, a) = (&*SRGB8_TO_LINEAR, &*UNORM8_TO_F32);
                fetch4(i, |i| decode8(c, a, v[i]))
            }
            Texels::Unorm8(v) => fetch4(i, |i| decode_unorm8(v[i])),
            Texels::Unorm8Recip(v) => fetch4(i, |i| decode_unorm8_recip(v[i])),
            Texels::Unorm16(v) => fetch4(i, |i| decode16(v[i])),
            Texels::F32(v) => fetch4(i, |i| v[i]),
        };
        let a = t00 * (1.0 - tx) + t10 * tx;
        let b = t01 * (1.0 - tx) + t11 * tx;
        a * (1.0 - ty) + b * ty
    }

    /// [`Texture::lookup_filtered`], reusing the texel addresses and weights of the hit's
    /// previous lookup in `shared` when that one read the same texel positions: a level-0
    /// bilinear lookup at the same uv (bits) of a texture with the same size, wrap modes and
    /// layout (ToyCar's body reads base colour, metallic-roughness and clearcoat, all 1024² and
    /// repeating, at uv set 0: the addressing — two floors, two wraps, four tiled indices — was
    /// about half of each lookup's instructions). Anything else (nearest filtering, MIP levels,
    /// a non-finite uv) is the plain lookup and leaves `shared` as it was. The result is bit for
    /// bit [`Texture::lookup_filtered`]'s.
    #[inline]
    pub fn lookup_shared(&self, uv: Vec2, duv: Vec4, shared: &Cell<SharedFootprint>) -> Vec4 {
        // The cases in which `lookup_filtered` reads level 0 bilinearly (through `lookup`).
        let level0 = self.mips.is_empty()
            || duv.abs().max_element() <= NO_FOOTPRINT
            || !(self.mip_level(duv) > 0.0);
        if !level0 || self.filter != FilterMode::Bilinear || !uv.is_finite() {
            return self.lookup_filtered(uv, duv);
        }
        let key = SharedFootprint {
            uv: [uv.x.to_bits(), uv.y.to_bits()],
            width: self.width,
            height: self.height,
            wrap_s: self.wrap_s,
            wrap_t: self.wrap_t,
            tiled: self.layout.tiled,
            tile_row: self.layout.tile_row,
            quad: [0; 4],
            tx: 0.0,
            ty: 0.0,
        };
        let mut fp = shared.get();
        if !fp.same_positions(&key) {
            // As `lookup` computes them, with the tiles' start left out (it is the one part of
            // an address that differs between textures of the same size and layout).
            let x = uv.x * self.width as f32;
            let y = uv.y * self.height as f32;
            let layout = TexelLayout {
                base: 0,
                ..self.layout
            };
            let (quad, tx, ty) = self.bilinear_address(self.width, self.height, layout, x, y);
            fp = SharedFootprint {
                quad,
                tx,
                ty,
                ..key
            };
            shared.set(fp);
        }
        // Row-major levels have no start offset (`TexelLayout::default`).
        let base = if self.layout.tiled {
            self.layout.base
        } else {
            0
        };
        let q = fp.quad;
        let quad = [q[0] + base, q[1] + base, q[2] + base, q[3] + base];
        Self::blend(&self.texels, quad, fp.tx, fp.ty)
    }

    /// The MIP level a lookup with UV derivatives `duv` = (∂u/∂x, ∂v/∂x, ∂u/∂y, ∂v/∂y) reads:
    /// log₂ of the footprint's larger side in level-0 texels (pbrt-v4 `MIPMap::Filter` takes
    /// the largest of the four derivatives as the filter width, as here, but doubles it;
    /// Trayecto takes one pixel's footprint, so a level-0 texel per pixel is level 0). Level
    /// ≤ 0 is magnification. Not clamped to the pyramid.
    #[inline]
    pub fn mip_level(&self, duv: Vec4) -> f32 {
        let (w, h) = (self.width as f32, self.height as f32);
        let width = (duv.x.abs() * w)
            .max(duv.y.abs() * h)
            .max(duv.z.abs() * w)
            .max(duv.w.abs() * h);
        width.max(1e-8).log2()
    }

    /// Looks up (u, v) filtered over the pixel footprint `duv` = (∂u/∂x, ∂v/∂x, ∂u/∂y, ∂v/∂y):
    /// trilinear (Williams 1983, "Pyramidal Parametrics"; pbrt-v4 `MIPMap::Filter` with
    /// `trilinear`), a blend of bilinear lookups in the two pyramid levels around
    /// [`Texture::mip_level`]. Without a pyramid, for a zero footprint or when magnifying, it is
    /// exactly [`Texture::lookup`].
    #[inline]
    pub fn lookup_filtered(&self, uv: Vec2, duv: Vec4) -> Vec4 {
        if self.mips.is_empty() || duv.abs().max_element() <= NO_FOOTPRINT || !uv.is_finite() {
            return self.lookup(uv);
        }
        let level = self.mip_level(duv);
        if !(level > 0.0) {
            return self.lookup(uv);
        }
        let last = self.mips.len() as f32;
        let level = level.min(last);
        let l0 = level.floor();
        let t = level - l0;
        let at = |l: usize| -> Vec4 {
            let (w, h, texels, layout) = if l == 0 {
                (self.width, self.height, &self.texels, self.layout)
            } else {
                let m = &self.mips[l - 1];
                (m.width, m.height, &m.texels, m.layout)
            };
            self.bilinear(w, h, texels, layout, uv.x * w as f32, uv.y * h as f32)
        };
        let l0 = l0 as usize;
        let a = at(l0);
        if t == 0.0 || l0 >= self.mips.len() {
            return a;
        }
        a * (1.0 - t) + at(l0 + 1) * t
    }

    /// Builds the MIP pyramid (levels 1… down to 1×1) if the texture allows it and has none.
    /// Each level halves each side (rounded down, at least 1) and averages with an exact
    /// area-weighted box, separably, in linear values, so a non-power-of-two side is handled
    /// and every level keeps the image's mean (up to the rounding of its storage). A level is
    /// stored in its image's storage kind (8-bit stays 8-bit), so the pyramid adds about a
    /// third to the texel memory.
    pub fn build_mips(&mut self) {
        // Tiling comes after the pyramid (World::build); a tiled texture gets none.
        if self.layout.tiled
            || !self.mipmap
            || !self.mips.is_empty()
            || self.width * self.height <= 1
        {
            return;
        }
        let (mut w, mut h) = (self.width as usize, self.height as usize);
        let mut cur: Vec<Vec4> = self.texels.to_f32();
        while w > 1 || h > 1 {
            let (nw, nh) = ((w / 2).max(1), (h / 2).max(1));
            // Along x, then along y.
            let rows: Vec<Vec4> = (0..h)
                .flat_map(|y| box_resample(&cur[y * w..(y + 1) * w], nw))
                .collect();
            let mut next = vec![Vec4::ZERO; nw * nh];
            for x in 0..nw {
                let col: Vec<Vec4> = (0..h).map(|y| rows[y * nw + x]).collect();
                for (y, v) in box_resample(&col, nh).into_iter().enumerate() {
                    next[y * nw + x] = v;
                }
            }
            self.mips.push(MipLevel {
                width: nw as u32,
                height: nh as u32,
                texels: self.texels.encode_like(&next),
                layout: TexelLayout::default(),
            });
            (w, h, cur) = (nw, nh, next);
        }
    }

    /// Bytes the MIP levels above level 0 take.
    pub fn mip_bytes(&self) -> usize {
        self.mips
            .iter()
            .map(|m| m.texels.len() * m.texels.bytes_per_texel())
            .sum()
    }

    /// Average texel value (for light power estimates).
    pub fn average(&self) -> Vec4 {
        if !self.layout.tiled {
            let sum: Vec4 = self.texels.iter().sum();
            return sum / self.texels.len().max(1) as f32;
        }
        // Row by row, as the row-major sum: the rounding does not depend on the layout.
        let sum: Vec4 = self.texels_row_major().sum();
        sum / (self.width as usize * self.height as usize).max(1) as f32
    }

    /// Replaces every texel by `f(texel)`; the result is stored as float.
    pub fn map_texels(&mut self, f: impl Fn(Vec4) -> Vec4) {
        self.mips.clear();
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
            mipmap: true,
            mips: Vec::new(),
            procedural: None,
            layout: TexelLayout::default(),
        }
    }

    /// `wrap_pair(i)` is `(wrap(i), wrap(i + 1))` for every wrap mode, size and index around and
    /// far outside the texture. Fails if the repeating neighbour does not wrap to 0 at n − 1.
    #[test]
    fn wrap_pair_is_two_wraps() {
        for mode in [
            WrapMode::Repeat,
            WrapMode::ClampToEdge,
            WrapMode::MirroredRepeat,
        ] {
            for n in 1..7u32 {
                for i in (-40..40).chain([i64::MIN / 4, -1 << 40, 1 << 40, i64::MAX / 4]) {
                    assert_eq!(
                        Texture::wrap_pair(i, n, mode),
                        (Texture::wrap(i, n, mode), Texture::wrap(i + 1, n, mode)),
                        "{mode:?} n={n} i={i}"
                    );
                }
            }
        }
    }

    /// The bilinear lookup as it was before it shared wraps between texels (`floor`, one wrap
    /// per texel): the optimised lookup must return the same bits for every storage kind and
    /// wrap mode at random and edge coordinates. Fails with any change to the texel indices,
    /// the weights or the decoding.
    #[test]
    fn bilinear_matches_the_per_texel_reference() {
        fn reference(t: &Texture, uv: Vec2) -> Vec4 {
            let (fx, fy) = (uv.x * t.width as f32 - 0.5, uv.y * t.height as f32 - 0.5);
            let (x0, y0) = (fx.floor(), fy.floor());
            let (tx, ty) = (fx - x0, fy - y0);
            let (x0, y0) = (x0 as i64, y0 as i64);
            let g = |x, y| t.texels.get(t.index_in(t.width, t.height, t.layout, x, y));
            let a = g(x0, y0) * (1.0 - tx) + g(x0 + 1, y0) * tx;
            let b = g(x0, y0 + 1) * (1.0 - tx) + g(x0 + 1, y0 + 1) * tx;
            a * (1.0 - ty) + b * ty
        }
        let (w, h) = (5u32, 3u32);
        let texels: Vec<Vec4> = (0..w * h)
            .map(|i| {
                let c = |k: u32| ((i * 37 + k * 101) % 256) as f32 / 255.0;
                Vec4::new(c(0), c(1), c(2), c(3))
            })
            .collect();
        // The float kind spans [−1, 2], beyond what the fixed-point kinds can hold.
        let kinds = storage_kinds(&texels, |v| v * 3.0 - Vec4::ONE);
        let mut uvs: Vec<Vec2> = Vec::new();
        let mut s = 0x1234_5678u32;
        let mut next = || {
            s ^= s << 13;
            s ^= s >> 17;
            s ^= s << 5;
            (s as f32 / u32::MAX as f32 - 0.5) * 6.0
        };
        for _ in 0..5_000 {
            uvs.push(Vec2::new(next(), next()));
        }
        for k in -12..=12 {
            // Texel edges and centres, where the floor and the wrap change.
            let e = k as f32 / 10.0;
            uvs.extend([
                Vec2::new(e, 1.0 - e),
                Vec2::new(0.1 / w as f32 * k as f32, e),
            ]);
        }
        uvs.extend([
            Vec2::ZERO,
            Vec2::ONE,
            Vec2::new(1e9, -1e9),
            Vec2::new(-0.0, 0.0),
        ]);
        for texels in kinds {
            for (ws, wt) in [
                (WrapMode::Repeat, WrapMode::Repeat),
                (WrapMode::ClampToEdge, WrapMode::MirroredRepeat),
                (WrapMode::MirroredRepeat, WrapMode::ClampToEdge),
            ] {
                let t = Texture {
                    wrap_s: ws,
                    wrap_t: wt,
                    ..Texture::with_texels("t", w, h, texels.clone())
                };
                for &uv in &uvs {
                    let (a, b) = (t.lookup(uv), reference(&t, uv));
                    assert_eq!(
                        a.to_array().map(f32::to_bits),
                        b.to_array().map(f32::to_bits),
                        "{} {ws:?}/{wt:?} at {uv:?}: {a:?} vs {b:?}",
                        t.texels.kind()
                    );
                }
            }
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

    /// The arithmetic 8-bit decoders are their tables bit for bit, in every lane, for every code
    /// (fails if, say, `decode_unorm8` multiplied by 1/255: codes differ by one ulp).
    #[test]
    fn unorm8_arithmetic_is_the_table() {
        for i in 0..=255u8 {
            let p = [i, i.wrapping_add(85), i.wrapping_add(170), 255 - i];
            let table = decode8(&UNORM8_TO_F32, &UNORM8_TO_F32, p);
            let recip = decode8(&UNORM8_TO_F32_RECIP, &UNORM8_TO_F32_RECIP, p);
            assert_eq!(
                decode_unorm8(p).to_array().map(f32::to_bits),
                table.to_array().map(f32::to_bits),
                "code {i}"
            );
            assert_eq!(
                decode_unorm8_recip(p).to_array().map(f32::to_bits),
                recip.to_array().map(f32::to_bits),
                "code {i}"
            );
        }
    }

    #[test]
    fn srgb_round_trip() {
        for c in [0.0f32, 0.001, 0.04, 0.5, 1.0] {
            assert!((linear_to_srgb(srgb_to_linear(c)) - c).abs() < 1e-5);
        }
        assert!((srgb_to_linear(0.5) - 0.214).abs() < 1e-3);
    }

    /// `UvTransform::apply` skips `sin_cos` for a rotation of +0 and uses (0, 1): that must be
    /// what `sin_cos` gives, bit for bit, or unrotated transforms would move; and −0, whose sine
    /// is −0, must still go through `sin_cos` (mirrored offsets keep their sign of zero).
    #[test]
    fn unrotated_transform_is_the_rotated_formula_at_zero() {
        let (s, c) = 0f32.sin_cos();
        assert_eq!((s.to_bits(), c.to_bits()), (0f32.to_bits(), 1f32.to_bits()));
        for rotation in [0.0f32, -0.0] {
            // A zero offset and uv keep the sign of zero visible: at uv (0, 0) the v result is
            // −sin·0 + cos·(−0) − 0, which is +0 for sin = −0 and −0 for sin = +0.
            let t = UvTransform {
                offset: Vec2::new(-0.0, -0.0),
                rotation,
                scale: Vec2::new(3.0, -2.0),
            };
            let (sin, cos) = rotation.sin_cos();
            for uv in [
                Vec2::ZERO,
                Vec2::new(0.0, -0.0),
                Vec2::new(0.3, 0.7),
                Vec2::new(-5.5, 1e-3),
            ] {
                let sc = uv * t.scale;
                let want = Vec2::new(cos * sc.x + sin * sc.y, -sin * sc.x + cos * sc.y) + t.offset;
                let got = t.apply(uv);
                assert_eq!(
                    (got.x.to_bits(), got.y.to_bits()),
                    (want.x.to_bits(), want.y.to_bits()),
                    "rotation {rotation:?} uv {uv:?}"
                );
            }
        }
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
    /// `texels` (components in [0, 1]) in every storage kind: the 8-bit ones (sRGB, linear and
    /// linear-by-division), 16-bit, and float with `float` applied to each texel.
    fn storage_kinds(texels: &[Vec4], float: impl Fn(Vec4) -> Vec4) -> [Texels; 5] {
        let bytes: Vec<[u8; 4]> = texels
            .iter()
            .map(|v| v.to_array().map(|c| (c * 255.0) as u8))
            .collect();
        [
            Texels::Srgb8(bytes.clone()),
            Texels::Unorm8(bytes.clone()),
            Texels::Unorm8Recip(bytes),
            Texels::Unorm16(
                texels
                    .iter()
                    .map(|v| v.to_array().map(|c| (c * 65535.0) as u16))
                    .collect(),
            ),
            Texels::F32(texels.iter().map(|&v| float(v)).collect()),
        ]
    }

    fn ramp(w: u32, h: u32) -> Vec<Vec4> {
        (0..w * h)
            .map(|i| {
                let (x, y) = ((i % w) as f32, (i / w) as f32);
                // A pattern with content at every frequency (no level averages it out early).
                let f =
                    |k: f32| ((x * k + y * 1.7).sin() * 0.5 + 0.5) * ((x + y) % 3.0 + 1.0) / 3.0;
                Vec4::new(f(0.9), f(2.3), f(0.31), 1.0 - f(1.1) * 0.5)
            })
            .collect()
    }

    fn mean(texels: &Texels) -> Vec4 {
        texels.iter().sum::<Vec4>() / texels.len() as f32
    }

    /// Every level of a non-power-of-two pyramid halves its sides (rounded down) and keeps the
    /// image's mean: exactly (f32 rounding) for float texels, within 8-bit rounding for sRGB.
    /// Fails with a box that drops the odd texel or point-samples (checked by replacing the
    /// overlap weights with 1/2 each: the mean of the 37-wide level moves by 2e-3).
    #[test]
    fn pyramid_keeps_the_mean_at_every_level() {
        let texels = ramp(37, 23);
        let m0 = texels.iter().sum::<Vec4>() / texels.len() as f32;
        for (kind, tol) in [("f32", 2e-6f32), ("srgb8", 2.5e-3)] {
            let stored = if kind == "f32" {
                Texels::F32(texels.clone())
            } else {
                Texels::Srgb8(
                    texels
                        .iter()
                        .map(|t| {
                            let q = |c: f32| (linear_to_srgb(c) * 255.0).round() as u8;
                            [q(t.x), q(t.y), q(t.z), (t.w * 255.0).round() as u8]
                        })
                        .collect(),
                )
            };
            let mut t = Texture::with_texels("r", 37, 23, stored);
            let base = mean(&t.texels);
            if kind == "f32" {
                assert!((base - m0).abs().max_element() < 1e-6);
            }
            t.build_mips();
            let sizes: Vec<(u32, u32)> = t.mips.iter().map(|m| (m.width, m.height)).collect();
            assert_eq!(sizes, [(18, 11), (9, 5), (4, 2), (2, 1), (1, 1)]);
            for m in &t.mips {
                assert_eq!(m.texels.kind(), kind);
                let d = (mean(&m.texels) - base).abs().max_element();
                assert!(
                    d <= tol,
                    "{kind} level {}x{}: mean off by {d}",
                    m.width,
                    m.height
                );
            }
            // About a third more memory (a 2D pyramid: 1/4 + 1/16 + … of level 0).
            let extra = t.mip_bytes() as f32 / t.texel_bytes() as f32;
            assert!(extra > 0.2 && extra < 0.4, "{extra}");
        }
    }

    /// Distinct texels (every channel differs between texels) of a `w` × `h` image.
    fn distinct(w: u32, h: u32) -> Vec<Vec4> {
        (0..w * h)
            .map(|i| {
                Vec4::new(
                    i as f32,
                    i as f32 + 0.25,
                    -(i as f32),
                    1.0 / (i as f32 + 1.0),
                )
            })
            .collect()
    }

    /// Every texel of a tiled level is addressable at its own index, inside the storage, and
    /// reads back as the row-major texel, for odd, non-power-of-two, thin and 1 × 1 sizes; the
    /// average keeps its bits; 8-bit tiles start on a cache line. Fails with a wrong tile stride
    /// (e.g. `tiles_x` rounded down instead of up: two texels of a 5-wide image collide).
    #[test]
    fn tiled_layout_addresses_every_texel_once() {
        for (w, h) in [
            (1, 1),
            (1, 7),
            (7, 1),
            (2, 2),
            (3, 5),
            (4, 4),
            (5, 3),
            (8, 8),
            (13, 6),
            (37, 23),
            (64, 17),
        ] {
            {
                let s = TILE_LOG2;
                let plain = Texture::with_texels("d", w, h, Texels::F32(distinct(w, h)));
                let mut t = plain.clone();
                t.tile();
                if w * h == 1 {
                    assert_eq!(t, plain, "a 1x1 texture stays as it is");
                    continue;
                }
                assert!(t.layout.tiled);
                // Whole tiles: the padded size, plus at most a cache line for alignment.
                let tiles = (w as usize).div_ceil(4) * (h as usize).div_ceil(4);
                assert!(t.texels.len() >= tiles * 16 && t.texels.len() < tiles * 16 + 4);
                let mut seen = vec![false; t.texels.len()];
                for y in 0..h as usize {
                    for x in 0..w as usize {
                        let i = t.layout.index(w, x, y);
                        assert!(i < t.texels.len(), "{w}x{h} s={s} ({x},{y}) -> {i}");
                        assert!(!seen[i], "{w}x{h} s={s}: ({x},{y}) shares index {i}");
                        seen[i] = true;
                        assert_eq!(t.texel(x, y), plain.texel(x, y), "{w}x{h} s={s} ({x},{y})");
                    }
                }
                let stored: Vec<Vec4> = t.texels_row_major().collect();
                assert_eq!(stored, plain.texels.to_f32());
                // Bits, not just values: the mean of the light estimates must not move.
                assert_eq!(
                    t.average().to_array().map(f32::to_bits),
                    plain.average().to_array().map(f32::to_bits)
                );
            }
            let mut t = Texture::with_texels(
                "b",
                w,
                h,
                Texels::Unorm8(vec![[7, 8, 9, 10]; (w * h) as usize]),
            );
            t.tile();
            if let Texels::Unorm8(v) = &t.texels {
                let addr = v.as_ptr() as usize + t.layout.base * 4;
                assert!(
                    w * h == 1 || addr.is_multiple_of(CACHE_LINE),
                    "{w}x{h}: tiles at {addr:#x}"
                );
            }
        }
    }

    /// Tiling changes where texels live, never a lookup: nearest, bilinear and trilinear lookups
    /// of the tiled texture return the row-major texture's bits for every storage kind and wrap
    /// mode, at random, edge and far-away coordinates, on odd and power-of-two sizes. Fails with
    /// any addressing error (swapping `col`'s low bits for the next tile's: thousands of lookups
    /// differ).
    #[test]
    fn tiled_lookups_are_bit_identical() {
        let mut state = 0x9e37_79b9u32;
        let mut next = move || {
            state ^= state << 13;
            state ^= state >> 17;
            state ^= state << 5;
            state as f32 / u32::MAX as f32
        };
        for (w, h) in [(1, 1), (1, 6), (5, 3), (8, 8), (37, 23), (64, 17)] {
            let texels = ramp(w, h);
            let kinds = storage_kinds(&texels, |v| v);
            for kind in kinds {
                for (ws, wt) in [
                    (WrapMode::Repeat, WrapMode::Repeat),
                    (WrapMode::ClampToEdge, WrapMode::MirroredRepeat),
                    (WrapMode::MirroredRepeat, WrapMode::ClampToEdge),
                ] {
                    for filter in [FilterMode::Nearest, FilterMode::Bilinear] {
                        let mut plain = Texture {
                            wrap_s: ws,
                            wrap_t: wt,
                            filter,
                            ..Texture::with_texels("t", w, h, kind.clone())
                        };
                        plain.build_mips();
                        let mut tiled = plain.clone();
                        tiled.tile();
                        assert_eq!(tiled.layout.tiled, w * h > 1);
                        let mut uvs: Vec<Vec2> = (0..600)
                            .map(|_| Vec2::new(next() * 5.0 - 2.0, next() * 5.0 - 2.0))
                            .collect();
                        for k in -8..=8 {
                            let e = k as f32 / 4.0;
                            uvs.extend([
                                Vec2::new(e, 0.0),
                                Vec2::new(0.0, e),
                                Vec2::new(e, 1.0 - e),
                                Vec2::new(k as f32 / w as f32, k as f32 / h as f32),
                            ]);
                        }
                        uvs.extend([Vec2::new(1e9, -1e9), Vec2::new(f32::NAN, 0.5)]);
                        for &uv in &uvs {
                            let bits = |t: &Texture, duv: Vec4| {
                                t.lookup_filtered(uv, duv).to_array().map(f32::to_bits)
                            };
                            for duv in [
                                Vec4::ZERO,
                                Vec4::new(3.0 / w as f32, 0.0, 0.0, 2.5 / h as f32),
                                Vec4::splat(next() * 0.5),
                            ] {
                                assert_eq!(
                                    bits(&tiled, duv),
                                    bits(&plain, duv),
                                    "{} {w}x{h} {ws:?}/{wt:?} {filter:?} uv {uv:?} duv {duv:?}",
                                    kind.kind()
                                );
                            }
                        }
                    }
                }
            }
        }
    }

    /// A run of lookups through one [`SharedFootprint`] — textures of every storage kind, both
    /// layouts, three sizes, three wrap-mode pairs, both filters, with and without a pyramid,
    /// each read at the same uvs in an interleaved order so the footprint is reused, replaced
    /// and skipped — returns [`Texture::lookup_filtered`]'s bits every time, and the footprint
    /// is reused (not recomputed) between same-keyed textures of different storage.
    #[test]
    fn shared_lookups_are_bit_identical() {
        let mut state = 0x2545_f491u32;
        let mut next = move || {
            state ^= state << 13;
            state ^= state >> 17;
            state ^= state << 5;
            state as f32 / u32::MAX as f32
        };
        // One group per size, each the same variants in the same order, interleaved below so
        // that consecutive textures differ in size only (same storage, wraps, filter, layout):
        // then only the footprint key's size fields tell them apart. 37×23, 37×29 and 38×23
        // share their tile-row stride (ten 4-texel tiles), so a key without the width or the
        // height would reuse another size's texel positions.
        let mut groups: Vec<Vec<Texture>> = Vec::new();
        for (w, h) in [(1, 1), (5, 3), (37, 23), (37, 29), (38, 23), (64, 64)] {
            let mut textures = Vec::new();
            let texels = ramp(w, h);
            for kind in storage_kinds(&texels, |v| v) {
                for (ws, wt) in [
                    (WrapMode::Repeat, WrapMode::Repeat),
                    (WrapMode::ClampToEdge, WrapMode::MirroredRepeat),
                    (WrapMode::MirroredRepeat, WrapMode::Repeat),
                ] {
                    for filter in [FilterMode::Nearest, FilterMode::Bilinear] {
                        let plain = Texture {
                            wrap_s: ws,
                            wrap_t: wt,
                            filter,
                            ..Texture::with_texels("t", w, h, kind.clone())
                        };
                        let mut mipped = plain.clone();
                        mipped.build_mips();
                        let (mut tiled, mut tiled_mipped) = (plain.clone(), mipped.clone());
                        tiled.tile();
                        tiled_mipped.tile();
                        textures.extend([plain, mipped, tiled, tiled_mipped]);
                    }
                }
            }
            groups.push(textures);
        }
        let grouped: Vec<Texture> = groups.concat();
        let interleaved: Vec<Texture> = (0..groups[0].len())
            .flat_map(|i| groups.iter().map(move |g| g[i].clone()))
            .collect();
        let mut uvs: Vec<Vec2> = (0..150)
            .map(|_| Vec2::new(next() * 5.0 - 2.0, next() * 5.0 - 2.0))
            .collect();
        uvs.extend([
            Vec2::ZERO,
            Vec2::new(-0.0, 1.0),
            Vec2::new(1e9, -1e9),
            Vec2::new(f32::NAN, 0.5),
        ]);
        let shared = Cell::new(SharedFootprint::NONE);
        let (mut reused, mut lookups) = (0, 0);
        for &uv in &uvs {
            for duv in [Vec4::ZERO, Vec4::splat(next() * 0.5)] {
                // Grouped by size forward then backward, so each texture follows textures of
                // other layouts as well as its own variants (the sharing counted below); then
                // interleaved, each texture after the same variant of another size.
                let passes = grouped.iter().chain(grouped.iter().rev());
                for (k, t) in passes.chain(interleaved.iter()).enumerate() {
                    let before = shared.get();
                    let got = t.lookup_shared(uv, duv, &shared);
                    let want = t.lookup_filtered(uv, duv);
                    assert_eq!(
                        got.to_array().map(f32::to_bits),
                        want.to_array().map(f32::to_bits),
                        "{} {}x{} {:?}/{:?} {:?} tiled {} mips {} uv {uv:?} duv {duv:?}",
                        t.texels.kind(),
                        t.width,
                        t.height,
                        t.wrap_s,
                        t.wrap_t,
                        t.filter,
                        t.layout.tiled,
                        t.mips.len()
                    );
                    // A level-0 bilinear lookup that left the footprint as it found it reused it.
                    let level0 = t.mips.is_empty() || duv == Vec4::ZERO;
                    if t.filter == FilterMode::Bilinear
                        && uv.is_finite()
                        && level0
                        && k < 2 * grouped.len()
                    {
                        lookups += 1;
                        if before.width != 0 && shared.get() == before {
                            reused += 1;
                        }
                    }
                }
            }
        }
        // Many level-0 bilinear lookups follow a same-keyed one (the storage kinds and pyramid
        // variants of a size, layout and wrap pair): the sharing is exercised, not bypassed
        // (58 112 of 119 340 when written).
        assert!(reused * 3 > lookups, "{reused} of {lookups} reused");
    }

    /// Without a footprint, or magnified, or without a pyramid, a filtered lookup is the plain
    /// one bit for bit; minified far enough it reads the coarsest level (the mean).
    #[test]
    fn filtered_lookup_is_the_plain_one_without_a_footprint() {
        let mut t = Texture::image("r", 37, 23, ramp(37, 23));
        let plain = t.clone();
        t.build_mips();
        for i in 0..200 {
            let uv = Vec2::new(i as f32 * 0.0137 - 0.5, i as f32 * 0.0291 - 1.0);
            let want = plain.lookup(uv).to_array().map(f32::to_bits);
            assert_eq!(
                t.lookup_filtered(uv, Vec4::ZERO)
                    .to_array()
                    .map(f32::to_bits),
                want
            );
            // One tenth of a texel per pixel: magnification.
            let small = Vec4::new(0.1 / 37.0, 0.0, 0.0, 0.1 / 23.0);
            assert_eq!(
                t.lookup_filtered(uv, small).to_array().map(f32::to_bits),
                want
            );
            assert_eq!(
                plain
                    .lookup_filtered(uv, Vec4::ONE)
                    .to_array()
                    .map(f32::to_bits),
                want
            );
        }
        let coarse = t.lookup_filtered(Vec2::new(0.3, 0.6), Vec4::splat(10.0));
        assert_eq!(coarse, t.mips.last().unwrap().texels.get(0));
        // Level: the larger side of the footprint in level-0 texels, log2.
        assert!((t.mip_level(Vec4::new(4.0 / 37.0, 0.0, 0.0, 1.0 / 23.0)) - 2.0).abs() < 1e-5);
        assert!((t.mip_level(Vec4::new(0.0, 8.0 / 23.0, 1.0 / 37.0, 0.0)) - 3.0).abs() < 1e-5);
    }
}
