//! Where FBX textures live. Decoding and the magenta fallback are shared with the other loaders
//! (`scene::image_io`); what is FBX-specific is finding the file.
//!
//! FBX stores a texture's path twice: `FileName`, usually absolute on the author's machine, and
//! `RelativeFilename`, relative to the .fbx. Both are tried, then the bare file name next to the
//! scene; only files inside the scene's folder are read. Embedded images (a `Video` node's
//! `Content`) are decoded from memory. Colour maps are sRGB-decoded to linear; data maps (normal
//! maps) stay linear.

use crate::material::texture::Texture;
use std::path::{Component, Path, PathBuf};

/// What went wrong resolving a texture; the caller turns it into a warning and a fallback.
pub type TextureResult = Result<Texture, String>;

/// Decodes image bytes (embedded or read from a file) to a linear RGBA texture, with the same
/// size limits and colour handling as every other loader.
pub fn decode(name: &str, bytes: &[u8], srgb: bool) -> TextureResult {
    crate::scene::image_io::decode_texture(name, bytes, srgb)
        .map_err(|e| format!("cannot decode '{name}': {e}"))
}

/// Lexically normalises a relative path; `None` if it climbs out of its base (`..` past the top)
/// or is absolute.
fn normalize_relative(p: &Path) -> Option<PathBuf> {
    let mut out = PathBuf::new();
    for c in p.components() {
        match c {
            Component::Normal(s) => out.push(s),
            Component::CurDir => {}
            Component::ParentDir => {
                if !out.pop() {
                    return None;
                }
            }
            Component::RootDir | Component::Prefix(_) => return None,
        }
    }
    Some(out)
}

/// Resolves a texture's file inside `scene_dir`, refusing anything that escapes it (`..`,
/// absolute paths elsewhere, symbolic links out of the folder).
pub fn resolve(
    scene_dir: &Path,
    relative: Option<&str>,
    absolute: Option<&str>,
) -> Result<PathBuf, String> {
    let root = scene_dir.canonicalize().map_err(|e| {
        format!(
            "cannot access the scene folder {}: {e}",
            scene_dir.display()
        )
    })?;
    let inside = |p: &Path| -> Option<PathBuf> {
        let c = p.canonicalize().ok()?;
        (c.starts_with(&root) && c.is_file()).then_some(c)
    };
    // FBX files written on Windows use backslashes.
    let clean = |s: &str| s.replace('\\', "/");
    let mut tried = Vec::new();
    let mut refused = Vec::new();
    for cand in [relative, absolute].into_iter().flatten() {
        let cand = clean(cand);
        if cand.is_empty() {
            continue;
        }
        let p = Path::new(&cand);
        if p.is_absolute() || cand.starts_with('/') || cand.get(1..2) == Some(":") {
            if let Some(c) = inside(p) {
                return Ok(c);
            }
            refused.push(cand.clone());
        } else if let Some(rel) = normalize_relative(p) {
            if let Some(c) = inside(&root.join(rel)) {
                return Ok(c);
            }
            tried.push(cand.clone());
        } else {
            refused.push(cand.clone());
        }
    }
    // Last resort: the bare file name next to the scene (textures copied along with the .fbx).
    for cand in [relative, absolute].into_iter().flatten() {
        let cand = clean(cand);
        if let Some(base) = cand
            .rsplit('/')
            .next()
            .filter(|b| !b.is_empty() && *b != "..")
            && let Some(c) = inside(&root.join(base))
        {
            return Ok(c);
        }
    }
    let mut msg = String::new();
    if !tried.is_empty() {
        msg.push_str(&format!("not found: {}", tried.join(", ")));
    }
    if !refused.is_empty() {
        if !msg.is_empty() {
            msg.push_str("; ");
        }
        msg.push_str(&format!(
            "refused (outside the scene folder): {}",
            refused.join(", ")
        ));
    }
    if msg.is_empty() {
        msg = "the texture names no file".into();
    }
    Err(msg)
}

/// Loads a texture file from inside `scene_dir`.
pub fn load(
    scene_dir: &Path,
    name: &str,
    relative: Option<&str>,
    absolute: Option<&str>,
    srgb: bool,
) -> TextureResult {
    let path = resolve(scene_dir, relative, absolute)?;
    let bytes = crate::limits::read_file(&path)
        .map_err(|e| format!("cannot read {}: {e}", path.display()))?;
    decode(name, &bytes, srgb)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::material::texture::srgb_to_linear;

    #[test]
    fn paths_escaping_the_scene_folder_are_refused() {
        let dir = std::env::temp_dir().join(format!("trayecto_fbx_tex_{}", std::process::id()));
        let sub = dir.join("scene");
        std::fs::create_dir_all(&sub).unwrap();
        std::fs::write(dir.join("secret.png"), b"x").unwrap();
        std::fs::write(sub.join("ok.png"), b"x").unwrap();
        let outside = dir.join("secret.png");
        let e = resolve(&sub, Some("../secret.png"), None).unwrap_err();
        assert!(e.contains("refused"), "{e}");
        let e = resolve(&sub, None, Some(outside.to_str().unwrap())).unwrap_err();
        assert!(e.contains("refused"), "{e}");
        // An absolute path from the author's machine falls back to the file next to the scene.
        let p = resolve(&sub, None, Some("C:\\Users\\me\\textures\\ok.png")).unwrap();
        assert!(p.ends_with("ok.png"));
        assert!(resolve(&sub, Some("./ok.png"), None).is_ok());
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn srgb_colour_maps_are_linearised() {
        let mut png = Vec::new();
        let img = image::RgbaImage::from_pixel(1, 1, image::Rgba([188, 255, 0, 128]));
        img.write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
            .unwrap();
        let t = decode("t", &png, true).unwrap();
        let v = t.texels.get(0);
        assert!((v.x - srgb_to_linear(188.0 / 255.0)).abs() < 1e-6);
        assert!((v.w - 128.0 / 255.0).abs() < 1e-6, "alpha stays linear");
        let lin = decode("t", &png, false).unwrap();
        assert!((lin.texels.get(0).x - 188.0 / 255.0).abs() < 1e-6);
    }
}
