//! Texture decoding shared by every loader (glTF, OBJ/MTL, TOML, FBX).
//!
//! * Colour textures (base colour, emissive, diffuse maps) are stored sRGB-encoded and are decoded
//!   to linear here; data textures (metallic-roughness, normal, occlusion) are read as they are.
//! * A texture that is missing or cannot be decoded is a warning, and the material gets a visible
//!   magenta fallback instead (docs/DESIGN.md §7), as model viewers do.
//! * Paths are resolved against the scene's folder and must stay inside it: absolute paths, `..`
//!   components, symbolic links that lead out and URIs with a scheme (`data:`, `http:`…) are
//!   refused. Only glTF may embed images, as base64 `data:` URIs or buffer views, and it decodes
//!   those itself through [`decode_texture`].

use std::path::{Component, Path, PathBuf};

use crate::material::texture::{FilterMode, srgb_to_linear};
use crate::material::{Texture, WrapMode};
use crate::math::Vec4;

/// The colour of a missing texture: loud on purpose.
pub const MISSING_TEXTURE_COLOR: Vec4 = Vec4::new(1.0, 0.0, 1.0, 1.0);

/// Name prefix of fallback textures, so loaders can tell them apart.
pub const MISSING_TEXTURE_PREFIX: &str = "missing texture: ";

/// Largest texture accepted (either side, in texels); the image crate also caps allocations.
const MAX_TEXTURE_SIDE: u32 = 16384;

/// The magenta texture used in place of one that could not be read.
pub fn missing_texture(name: &str) -> Texture {
    Texture::constant(
        &format!("{MISSING_TEXTURE_PREFIX}{name}"),
        MISSING_TEXTURE_COLOR,
    )
}

/// True for the fallback made by [`missing_texture`].
pub fn is_missing_texture(t: &Texture) -> bool {
    t.name.starts_with(MISSING_TEXTURE_PREFIX)
}

/// Decodes percent-escapes (`%20`) as glTF URIs use them. Invalid escapes are kept verbatim.
pub fn percent_decode(s: &str) -> String {
    let b = s.as_bytes();
    let mut out = Vec::with_capacity(b.len());
    let mut i = 0;
    while i < b.len() {
        if b[i] == b'%'
            && let Some(hex) = b.get(i + 1..i + 3)
            && let Ok(hs) = std::str::from_utf8(hex)
            && let Ok(v) = u8::from_str_radix(hs, 16)
        {
            out.push(v);
            i += 3;
            continue;
        }
        out.push(b[i]);
        i += 1;
    }
    String::from_utf8_lossy(&out).into_owned()
}

/// Resolves `relative_path` (a file name as written in a scene file, `/` or `\` separated) inside
/// `scene_dir`. Refuses anything that could read outside that folder.
pub fn resolve_in_dir(scene_dir: &Path, relative_path: &str) -> Result<PathBuf, String> {
    let trimmed = relative_path.trim();
    if trimmed.is_empty() {
        return Err("empty file name".into());
    }
    let lower = trimmed.to_ascii_lowercase();
    if lower.starts_with("data:") || trimmed.contains("://") {
        return Err(format!(
            "'{}' is a URI; only files beside the scene are read",
            shorten(trimmed)
        ));
    }
    // Scene files written on Windows use backslashes.
    let normalised = trimmed.replace('\\', "/");
    let rel = Path::new(&normalised);
    for c in rel.components() {
        match c {
            Component::Normal(_) | Component::CurDir => {}
            Component::ParentDir => {
                return Err(format!(
                    "'{trimmed}' goes up out of the scene's folder ('..' is not allowed)"
                ));
            }
            Component::RootDir | Component::Prefix(_) => {
                return Err(format!(
                    "'{trimmed}' is an absolute path; paths must be relative to the scene's folder"
                ));
            }
        }
    }
    // Drive letters (`C:/...`) are not components on Unix.
    if normalised.len() >= 2 && normalised.as_bytes()[1] == b':' {
        return Err(format!(
            "'{trimmed}' is an absolute path; paths must be relative to the scene's folder"
        ));
    }
    let full = scene_dir.join(rel);
    // Symbolic links must not lead out either.
    if let (Ok(real), Ok(root)) = (full.canonicalize(), scene_dir.canonicalize())
        && !real.starts_with(&root)
    {
        return Err(format!("'{trimmed}' leads outside the scene's folder"));
    }
    Ok(full)
}

fn shorten(s: &str) -> String {
    if s.chars().count() > 40 {
        let head: String = s.chars().take(40).collect();
        format!("{head}…")
    } else {
        s.to_string()
    }
}

/// Decodes an encoded image (PNG, JPEG, HDR) into a texture. `srgb` converts the colour channels
/// from sRGB to linear; alpha is always linear.
pub fn decode_texture(name: &str, bytes: &[u8], srgb: bool) -> Result<Texture, String> {
    let reader = reader_for(name, bytes)?;
    if reader.format().is_none() {
        return Err("unknown image format".into());
    }
    let (w, h) = reader.into_dimensions().map_err(|e| e.to_string())?;
    if w == 0 || h == 0 || w > MAX_TEXTURE_SIDE || h > MAX_TEXTURE_SIDE {
        return Err(format!("image size {w}×{h} is not supported"));
    }
    let img = reader_for(name, bytes)?
        .decode()
        .map_err(|e| e.to_string())?;
    let (w, h) = (img.width(), img.height());
    if w == 0 || h == 0 {
        return Err("image has no pixels".into());
    }
    let hdr = matches!(
        img.color(),
        image::ColorType::Rgb32F | image::ColorType::Rgba32F
    );
    let texels: Vec<Vec4> = if !hdr && srgb && img.color().bytes_per_pixel() <= 4 {
        // 8-bit sRGB: a lookup table instead of a powf per channel.
        let lut: Vec<f32> = (0..256).map(|i| srgb_to_linear(i as f32 / 255.0)).collect();
        img.to_rgba8()
            .pixels()
            .map(|p| {
                Vec4::new(
                    lut[p[0] as usize],
                    lut[p[1] as usize],
                    lut[p[2] as usize],
                    p[3] as f32 / 255.0,
                )
            })
            .collect()
    } else {
        // Floating-point images are already linear.
        let convert = srgb && !hdr;
        img.to_rgba32f()
            .pixels()
            .map(|p| {
                let c = |v: f32| if convert { srgb_to_linear(v) } else { v };
                Vec4::new(c(p[0]), c(p[1]), c(p[2]), p[3])
            })
            .collect()
    };
    Ok(Texture {
        name: name.to_string(),
        width: w,
        height: h,
        texels,
        wrap_s: WrapMode::Repeat,
        wrap_t: WrapMode::Repeat,
        filter: FilterMode::Bilinear,
    })
}

/// An image reader with the format guessed from the bytes, or else from the name's extension
/// (TGA has no signature to guess from).
fn reader_for<'a>(
    name: &str,
    bytes: &'a [u8],
) -> Result<image::ImageReader<std::io::Cursor<&'a [u8]>>, String> {
    let mut reader = image::ImageReader::new(std::io::Cursor::new(bytes))
        .with_guessed_format()
        .map_err(|e| e.to_string())?;
    if reader.format().is_none()
        && let Ok(f) = image::ImageFormat::from_path(name)
    {
        reader.set_format(f);
    }
    Ok(reader)
}

/// Why a texture path was refused (as opposed to merely missing).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RefusedPath(pub String);

/// Reads a texture file beside a scene. A refused path (outside the folder, a URI) is an error
/// for the loader to report; a missing or undecodable file is a warning in `warnings` and the
/// magenta fallback.
pub fn load_texture_checked(
    scene_dir: &Path,
    relative_path: &str,
    srgb: bool,
    warnings: &mut Vec<String>,
) -> Result<Texture, RefusedPath> {
    let path = resolve_in_dir(scene_dir, relative_path).map_err(RefusedPath)?;
    let bytes = match std::fs::read(&path) {
        Ok(b) => b,
        Err(e) => {
            warnings.push(format!(
                "texture '{relative_path}' could not be read ({e}): using a magenta fallback"
            ));
            return Ok(missing_texture(relative_path));
        }
    };
    match decode_texture(relative_path, &bytes, srgb) {
        Ok(t) => Ok(t),
        Err(e) => {
            warnings.push(format!(
                "texture '{relative_path}' could not be decoded ({e}): using a magenta fallback"
            ));
            Ok(missing_texture(relative_path))
        }
    }
}

/// Reads a texture file beside a scene (the entry point FBX and other loaders share).
///
/// Returns the decoded texture; a missing or undecodable file gives the magenta fallback and a
/// warning; a path that would leave the scene's folder (or a URI) gives `None` and a warning.
/// Loaders that want refusal to be an error use [`load_texture_checked`].
pub fn load_texture(
    scene_dir: &Path,
    relative_path: &str,
    srgb: bool,
    warnings: &mut Vec<String>,
) -> Option<Texture> {
    match load_texture_checked(scene_dir, relative_path, srgb, warnings) {
        Ok(t) => Some(t),
        Err(RefusedPath(why)) => {
            warnings.push(format!("texture refused: {why}"));
            None
        }
    }
}

/// Packs separate roughness and metalness maps (OBJ `map_Pr`, `map_Pm`, first channel each) into
/// one glTF-layout texture: roughness in G, metalness in B. Sizes may differ: the result has the
/// larger size and samples each source at the nearest texel. Missing sources read as 1 (the
/// factors then carry the value, as in glTF).
pub fn pack_metallic_roughness(
    roughness: Option<&Texture>,
    metallic: Option<&Texture>,
) -> Option<Texture> {
    if roughness.is_none() && metallic.is_none() {
        return None;
    }
    let w = roughness
        .map_or(1, |t| t.width)
        .max(metallic.map_or(1, |t| t.width));
    let h = roughness
        .map_or(1, |t| t.height)
        .max(metallic.map_or(1, |t| t.height));
    let sample = |t: Option<&Texture>, x: u32, y: u32| -> f32 {
        t.map_or(1.0, |t| {
            let tx = (x as u64 * t.width as u64 / w as u64) as usize;
            let ty = (y as u64 * t.height as u64 / h as u64) as usize;
            t.texels
                .get(ty * t.width as usize + tx)
                .map_or(1.0, |v| v.x)
        })
    };
    let mut texels = Vec::with_capacity(w as usize * h as usize);
    for y in 0..h {
        for x in 0..w {
            texels.push(Vec4::new(
                1.0,
                sample(roughness, x, y),
                sample(metallic, x, y),
                1.0,
            ));
        }
    }
    Some(Texture {
        name: "metallic-roughness (packed)".into(),
        width: w,
        height: h,
        texels,
        wrap_s: WrapMode::Repeat,
        wrap_t: WrapMode::Repeat,
        filter: FilterMode::Bilinear,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn refuses_paths_that_escape() {
        let dir = Path::new(".");
        assert!(resolve_in_dir(dir, "../secret.png").is_err());
        assert!(resolve_in_dir(dir, "a/../../b.png").is_err());
        assert!(resolve_in_dir(dir, "/etc/passwd").is_err());
        assert!(resolve_in_dir(dir, "..\\x.png").is_err());
        assert!(resolve_in_dir(dir, "C:\\x.png").is_err());
        assert!(resolve_in_dir(dir, "data:image/png;base64,AAAA").is_err());
        assert!(resolve_in_dir(dir, "http://example.com/x.png").is_err());
        assert!(resolve_in_dir(dir, "textures/wood.png").is_ok());
        assert!(resolve_in_dir(dir, "./wood.png").is_ok());
    }

    #[test]
    fn percent_decoding() {
        assert_eq!(percent_decode("a%20b.png"), "a b.png");
        assert_eq!(percent_decode("100%"), "100%");
        assert_eq!(percent_decode("%2e%2e/x"), "../x");
    }

    #[test]
    fn srgb_and_linear_decoding_differ() {
        // A 1×1 PNG with value 128 in every channel.
        let mut png = Vec::new();
        image::RgbaImage::from_pixel(1, 1, image::Rgba([128, 128, 128, 255]))
            .write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
            .unwrap();
        let s = decode_texture("t", &png, true).unwrap();
        let l = decode_texture("t", &png, false).unwrap();
        assert!((s.texels[0].x - srgb_to_linear(128.0 / 255.0)).abs() < 1e-6);
        assert!((l.texels[0].x - 128.0 / 255.0).abs() < 1e-6);
        assert_eq!(s.texels[0].w, 1.0);
        assert!(decode_texture("t", b"not an image", true).is_err());
    }

    #[test]
    fn missing_file_gives_magenta_and_warning() {
        let mut w = Vec::new();
        let t = load_texture(Path::new("."), "no_such_texture.png", true, &mut w).unwrap();
        assert!(is_missing_texture(&t));
        assert_eq!(t.texels[0], MISSING_TEXTURE_COLOR);
        assert_eq!(w.len(), 1);
        assert!(w[0].contains("no_such_texture.png"));
        let mut w = Vec::new();
        assert!(load_texture(Path::new("."), "../x.png", true, &mut w).is_none());
        assert_eq!(w.len(), 1);
    }
}
