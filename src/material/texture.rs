//! Image textures: linear float RGBA texels, bilinear or nearest lookup with glTF wrap modes and an
//! optional `KHR_texture_transform`.

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

/// A decoded image. Colour textures are converted from sRGB to linear when loaded.
#[derive(Clone, Debug, PartialEq)]
pub struct Texture {
    pub name: String,
    pub width: u32,
    pub height: u32,
    /// Row-major, top row first (as images are stored), linear RGBA.
    pub texels: Vec<Vec4>,
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
    /// A constant 1×1 texture.
    pub fn constant(name: &str, v: Vec4) -> Texture {
        Texture {
            name: name.to_string(),
            width: 1,
            height: 1,
            texels: vec![v],
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
    fn texel(&self, x: i64, y: i64) -> Vec4 {
        let xi = Self::wrap(x, self.width, self.wrap_s);
        let yi = Self::wrap(y, self.height, self.wrap_t);
        self.texels[yi * self.width as usize + xi]
    }

    /// Looks up (u, v) with v = 0 at the top row (glTF convention).
    #[inline]
    pub fn lookup(&self, uv: Vec2) -> Vec4 {
        if !uv.is_finite() {
            return self.texels[0];
        }
        let x = uv.x * self.width as f32;
        let y = uv.y * self.height as f32;
        match self.filter {
            FilterMode::Nearest => self.texel(x.floor() as i64, y.floor() as i64),
            FilterMode::Bilinear => {
                let (fx, fy) = (x - 0.5, y - 0.5);
                let (x0, y0) = (fx.floor(), fy.floor());
                let (tx, ty) = (fx - x0, fy - y0);
                let (x0, y0) = (x0 as i64, y0 as i64);
                let a = self.texel(x0, y0) * (1.0 - tx) + self.texel(x0 + 1, y0) * tx;
                let b = self.texel(x0, y0 + 1) * (1.0 - tx) + self.texel(x0 + 1, y0 + 1) * tx;
                a * (1.0 - ty) + b * ty
            }
        }
    }

    /// Average texel value (for light power estimates).
    pub fn average(&self) -> Vec4 {
        let sum: Vec4 = self.texels.iter().copied().sum();
        sum / self.texels.len().max(1) as f32
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
            texels: vec![Vec4::ZERO, Vec4::ONE, Vec4::ONE, Vec4::ZERO],
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
