//! Reading images, for everything that reads one: textures for every loader (glTF, OBJ/MTL,
//! TOML, FBX, pbrt), environment maps ([`read_rgb`]), reference and checkpoint images
//! ([`read_exr`], [`read_exr_channels`]). The image writers are `film::output`.
//!
//! * Colour textures (base colour, emissive, diffuse maps) are stored sRGB-encoded and are decoded
//!   to linear here; data textures (metallic-roughness, normal, occlusion) are read as they are.
//! * A texture that is missing or cannot be decoded is a warning, and the material gets a visible
//!   magenta fallback instead (docs/DESIGN.md §7), as model viewers do.
//! * Paths are resolved against the scene's folder and must stay inside it: absolute paths, `..`
//!   components, symbolic links that lead out and URIs with a scheme (`data:`, `http:`…) are
//!   refused. Only glTF may embed images, as base64 `data:` URIs or buffer views, and it decodes
//!   those itself through [`decode_texture`].

use crate::limits::PathRule;
use rayon::prelude::*;
use std::path::{Component, Path, PathBuf};

use crate::material::Texture;
use crate::material::texture::{
    Texels, UNORM8_TO_F32, UNORM8_TO_F32_RECIP, decode8, decode16, srgb_to_linear,
};
use crate::math::{Vec3, Vec4};

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

/// Resolves `relative_path` (a file name as written in a scene file, `/` or `\` separated)
/// against `scene_dir`, by the load's [`PathRule`] ([`crate::limits::path_rule`]): every loader
/// resolves the files a scene names here. Confined (the server's rule) refuses anything that
/// could read outside that folder; open (the command line's) reads what the file names, as
/// pbrt-v4, Mitsuba and Blender do. URIs are refused under both.
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
    if crate::limits::path_rule() == PathRule::Open {
        // `join` keeps an absolute path as it is.
        return Ok(scene_dir.join(rel));
    }
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
    // Symbolic links must not lead out either. A scene named without a folder (`scene.toml`)
    // has the empty path as its folder, which does not canonicalize: it is the current one.
    let root = if scene_dir.as_os_str().is_empty() {
        Path::new(".")
    } else {
        scene_dir
    };
    if let (Ok(real), Ok(root)) = (full.canonicalize(), root.canonicalize())
        && !real.starts_with(&root)
    {
        return Err(format!(
            "'{trimmed}' leads outside the scene's folder (only the command line, without \
             --confine-paths, reads files outside it)"
        ));
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
    decode_image(name, bytes).and_then(|img| texture_from_image(name, &img, srgb))
}

/// Decodes an encoded image (PNG, JPEG, WebP, HDR, TGA, KTX2 / Basis Universal), refusing absurd
/// sizes before decoding. The format is guessed from the bytes, else from `name`'s extension.
pub fn decode_image(name: &str, bytes: &[u8]) -> Result<image::DynamicImage, String> {
    if bytes.starts_with(&KTX2_IDENTIFIER) {
        return decode_ktx2(bytes);
    }
    let mut reader = reader_for(name, bytes)?;
    if reader.format().is_none() {
        return Err("unknown image format".into());
    }
    // The decoder may allocate no more than the load's budget has left (docs/DESIGN.md §7,
    // "Bounded loads"); its own size limits are the texture limits.
    let mut limits = image::Limits::default();
    limits.max_image_width = Some(MAX_TEXTURE_SIDE);
    limits.max_image_height = Some(MAX_TEXTURE_SIDE);
    let ctx = crate::limits::current();
    limits.max_alloc = Some(ctx.budget.limit().saturating_sub(ctx.budget.used()));
    reader.limits(limits);
    let decoder = reader.into_decoder().map_err(|e| e.to_string())?;
    let (w, h) = image::ImageDecoder::dimensions(&decoder);
    if w == 0 || h == 0 || w > MAX_TEXTURE_SIDE || h > MAX_TEXTURE_SIDE {
        return Err(format!("image size {w}×{h} is not supported"));
    }
    // The pixels as decoded, checked from the header before decoding (texture_from_image
    // checks what it makes of them before it converts).
    let decoded = image::ImageDecoder::total_bytes(&decoder);
    let _decoding = ctx
        .reserve(decoded, || format!("the {w}×{h} image '{}'", shorten(name)))
        .map_err(|e| e.to_string())?;
    image::DynamicImage::from_decoder(decoder).map_err(|e| e.to_string())
}

/// What [`texture_from_image`] may hold per texel at its peak besides the texels it keeps: the
/// RGBA float copy, the float texels and the compact codes it compares them with (the 8-bit
/// sRGB path holds only an RGBA8 copy).
const TEXTURE_BYTES_PER_TEXEL: u64 = 16 + 16 + 8 + 8;

/// A decoded image as a texture. `srgb` converts the colour channels from sRGB to linear; alpha
/// is always linear.
pub fn texture_from_image(
    name: &str,
    img: &image::DynamicImage,
    srgb: bool,
) -> Result<Texture, String> {
    let (w, h) = (img.width(), img.height());
    if w == 0 || h == 0 {
        return Err("image has no pixels".into());
    }
    let hdr = matches!(
        img.color(),
        image::ColorType::Rgb32F | image::ColorType::Rgba32F
    );
    let srgb8 = !hdr && srgb && img.color().bytes_per_pixel() <= 4;
    // The conversion's copies, reserved before converting and returned when it ends; the
    // texels kept (4 to 16 bytes each) are charged on top before the copies are freed.
    let texels_n = u64::from(w) * u64::from(h);
    let working = if srgb8 { 4 } else { TEXTURE_BYTES_PER_TEXEL };
    let _working = crate::limits::reserve(texels_n * working, || {
        format!("the {w}×{h} texture '{}'", shorten(name))
    })?;
    let keep = |t: Texture| -> Result<Texture, String> {
        crate::limits::charge(texels_n * t.texels.bytes_per_texel() as u64, || {
            format!("the {w}×{h} texture '{}'", shorten(name))
        })?;
        Ok(t)
    };
    // Texels keep the file's precision and are decoded at lookup (material::texture::Texels):
    // the lookups return exactly the values this function used to store as float.
    let bytes_per_channel = img.color().bytes_per_pixel() / img.color().channel_count();
    if srgb8 {
        // 8-bit sRGB (16-bit grey with or without alpha is reduced to 8 bits here, as before):
        // the table holds srgb_to_linear(i / 255), alpha i / 255.
        let texels = Texels::Srgb8(as_quads(img.to_rgba8().as_raw()));
        return keep(Texture::with_texels(name, w, h, texels));
    }
    // Floating-point images are already linear; 16-bit sRGB is decoded to float here.
    let convert = srgb && !hdr;
    let float: Vec<Vec4> = img
        .to_rgba32f()
        .as_raw()
        // Per texel and independent: rayon keeps the order, so the result is the same for any
        // thread count (big textures dominate a model's load time).
        .par_chunks_exact(4)
        .map(|p| {
            let c = |v: f32| if convert { srgb_to_linear(v) } else { v };
            Vec4::new(c(p[0]), c(p[1]), c(p[2]), p[3])
        })
        .collect();
    // Linear integer images keep their codes when a decoder reproduces the float conversion
    // exactly, texel by texel (the image crate divides for some layouts and multiplies by the
    // reciprocal for others, so this is checked, not assumed).
    let same = |codes: &[[u8; 4]], lut: &[f32; 256]| {
        codes
            .par_iter()
            .zip(&float)
            .all(|(c, f)| same_bits(decode8(lut, lut, *c), *f))
    };
    let texels = if !convert && !hdr && bytes_per_channel == 1 {
        let codes = as_quads(img.to_rgba8().as_raw());
        if same(&codes, &UNORM8_TO_F32) {
            Texels::Unorm8(codes)
        } else if same(&codes, &UNORM8_TO_F32_RECIP) {
            Texels::Unorm8Recip(codes)
        } else {
            Texels::F32(float)
        }
    } else if !convert && !hdr && bytes_per_channel == 2 {
        let codes = as_quads(img.to_rgba16().as_raw());
        if codes
            .par_iter()
            .zip(&float)
            .all(|(c, f)| same_bits(decode16(*c), *f))
        {
            Texels::Unorm16(codes)
        } else {
            Texels::F32(float)
        }
    } else {
        Texels::F32(float)
    };
    keep(Texture::with_texels(name, w, h, texels))
}

fn same_bits(a: Vec4, b: Vec4) -> bool {
    a.to_array().map(f32::to_bits) == b.to_array().map(f32::to_bits)
}

/// Interleaved RGBA channels as one array per texel.
fn as_quads<T: Copy + Default>(raw: &[T]) -> Vec<[T; 4]> {
    raw.chunks_exact(4)
        .map(|p| [p[0], p[1], p[2], p[3]])
        .collect()
}

/// The 12 bytes every KTX 2.0 file starts with (KTX 2.0 specification §3.1).
const KTX2_IDENTIFIER: [u8; 12] = *b"\xABKTX 20\xBB\r\n\x1A\n";

/// Decodes the base level of a KTX2 file holding Basis Universal data (ETC1S/BasisLZ or UASTC,
/// optionally Zstandard-supercompressed: what `KHR_texture_basisu` allows) to 8-bit RGBA, with
/// the pure-Rust `basisu` transcoder. The texel order is kept: glTF's KTX2 images are stored
/// top row first, like PNG (KHR_texture_basisu, "KTX2 orientation").
///
/// The transcoder trusts the sizes in the file's level index (it allocates a level's declared
/// uncompressed length before inflating it), so the header is checked here first: the image
/// size against [`MAX_TEXTURE_SIDE`], and every level's byte range and uncompressed length
/// against the file and what a 2D Basis image of that size can hold (16 bytes per 4×4 block).
pub fn decode_ktx2(bytes: &[u8]) -> Result<image::DynamicImage, String> {
    let u32_at = |o: usize| -> Result<u32, String> {
        bytes
            .get(o..o + 4)
            .map(|b| u32::from_le_bytes(b.try_into().expect("4 bytes")))
            .ok_or_else(|| "truncated KTX2 header".to_string())
    };
    let u64_at = |o: usize| -> Result<u64, String> {
        bytes
            .get(o..o + 8)
            .map(|b| u64::from_le_bytes(b.try_into().expect("8 bytes")))
            .ok_or_else(|| "truncated KTX2 level index".to_string())
    };
    let (vk_format, w, h) = (u32_at(12)?, u32_at(20)?, u32_at(24)?);
    let (depth, layers, faces, levels) = (u32_at(28)?, u32_at(32)?, u32_at(36)?, u32_at(40)?);
    let scheme = u32_at(44)?;
    if w == 0 || h == 0 || w > MAX_TEXTURE_SIDE || h > MAX_TEXTURE_SIDE {
        return Err(format!("KTX2 image size {w}×{h} is not supported"));
    }
    if depth > 1 || layers > 1 || faces != 1 {
        return Err(format!(
            "KTX2 image is not a single 2D image ({depth} deep, {layers} layers, {faces} faces)"
        ));
    }
    if vk_format != 0 {
        return Err(format!(
            "KTX2 image has vkFormat {vk_format}; only Basis Universal data (vkFormat 0: ETC1S or UASTC) is decoded"
        ));
    }
    // Upper bound of one level's data: 16 bytes per 4×4 block of the base level.
    let bound = u64::from(w.div_ceil(4)) * u64::from(h.div_ceil(4)) * 16;
    for level in 0..levels.clamp(1, 32) as usize {
        let at = 80 + 24 * level;
        let (offset, length, uncompressed) = (u64_at(at)?, u64_at(at + 8)?, u64_at(at + 16)?);
        if offset
            .checked_add(length)
            .is_none_or(|end| end > bytes.len() as u64)
        {
            return Err(format!(
                "KTX2 level {level} (bytes {offset}..+{length}) lies outside the file of {} bytes",
                bytes.len()
            ));
        }
        if uncompressed > bound || (scheme == 2 && uncompressed == 0) {
            return Err(format!(
                "KTX2 level {level} declares {uncompressed} uncompressed bytes, impossible for a {w}×{h} Basis image"
            ));
        }
    }
    let tex = basisu::Transcoder::new(bytes)
        .map_err(|e| format!("not a valid KTX2 / Basis Universal image ({e:?})"))?;
    let (tw, th) = tex.base_dimensions();
    if (tw, th) != (w, h) {
        return Err(format!(
            "KTX2 image size {tw}×{th} disagrees with its header"
        ));
    }
    let rgba = tex
        .transcode(0, basisu::TargetFormat::Rgba32, basisu::DecodeFlags::NONE)
        .map_err(|e| {
            format!(
                "KTX2 image ({:?}) cannot be transcoded to RGBA ({e:?})",
                tex.source_format()
            )
        })?;
    image::RgbaImage::from_raw(w, h, rgba)
        .map(image::DynamicImage::ImageRgba8)
        .ok_or_else(|| "KTX2 transcoder returned the wrong amount of data".to_string())
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
    let bytes = match crate::limits::read_file(&path) {
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
                .try_get(ty * t.width as usize + tx)
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
    Some(Texture::image("metallic-roughness (packed)", w, h, texels))
}

/// Portable float map: `PF` (RGB) or `Pf` (grey), width height, scale (negative = little
/// endian), then rows bottom to top.
pub fn decode_pfm(name: &str, bytes: &[u8]) -> Result<Texture, String> {
    let mut fields = Vec::new();
    let mut pos = 0;
    while fields.len() < 4 {
        while pos < bytes.len() && bytes[pos].is_ascii_whitespace() {
            pos += 1;
        }
        let start = pos;
        while pos < bytes.len() && !bytes[pos].is_ascii_whitespace() {
            pos += 1;
        }
        if start == pos || pos - start > 32 {
            return Err("truncated PFM header".into());
        }
        fields.push(String::from_utf8_lossy(&bytes[start..pos]).into_owned());
    }
    pos += 1; // the single whitespace byte after the scale
    let channels = match fields[0].as_str() {
        "PF" => 3,
        "Pf" => 1,
        _ => return Err("not a PFM file".into()),
    };
    let w: u32 = fields[1].parse().map_err(|_| "bad PFM width")?;
    let h: u32 = fields[2].parse().map_err(|_| "bad PFM height")?;
    let scale: f32 = fields[3].parse().map_err(|_| "bad PFM scale")?;
    if w == 0 || h == 0 || w > 16384 || h > 16384 || !scale.is_finite() || scale == 0.0 {
        return Err(format!(
            "PFM size {w}×{h} or scale {scale} is not supported"
        ));
    }
    crate::limits::charge(u64::from(w) * u64::from(h) * 16, || {
        format!("the {w}×{h} PFM image '{}'", shorten(name))
    })?;
    let n = w as usize * h as usize * channels;
    let data = bytes
        .get(pos..pos + n * 4)
        .ok_or("the PFM file is shorter than its header says")?;
    let little = scale < 0.0;
    let mut texels = vec![Vec4::ZERO; w as usize * h as usize];
    for y in 0..h as usize {
        // PFM rows run bottom to top; textures are stored top row first.
        let dst_row = h as usize - 1 - y;
        for x in 0..w as usize {
            let mut c = [0.0f32; 3];
            for (k, ck) in c.iter_mut().enumerate().take(channels) {
                let i = ((y * w as usize + x) * channels + k) * 4;
                let b = [data[i], data[i + 1], data[i + 2], data[i + 3]];
                let v = if little {
                    f32::from_le_bytes(b)
                } else {
                    f32::from_be_bytes(b)
                };
                *ck = if v.is_finite() { v } else { 0.0 };
            }
            if channels == 1 {
                c = [c[0]; 3];
            }
            texels[dst_row * w as usize + x] = Vec4::new(c[0], c[1], c[2], 1.0);
        }
    }
    Ok(Texture::image(name, w, h, texels))
}

/// An error reading an image file.
#[derive(Debug, thiserror::Error)]
#[error("{path}: {message}")]
pub struct ReadError {
    pub path: PathBuf,
    pub message: String,
}

/// An EXR's size and its channels (name, values in row order), as [`read_exr_channels`] reads them.
pub type ExrChannels = (u32, u32, Vec<(String, Vec<f32>)>);

/// Every channel of a single-part EXR by name (for tests and tools reading AOVs back).
pub fn read_exr_channels(path: &Path) -> Result<ExrChannels, ReadError> {
    use exr::prelude::*;
    let rerr = |m: String| ReadError {
        path: path.to_path_buf(),
        message: m,
    };
    // Every channel as stored (at most 4 bytes a sample) and as f32.
    check_exr_header(path, |channels| 8 * channels).map_err(rerr)?;
    let img = read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .first_valid_layer()
        .all_attributes()
        .from_file(path)
        .map_err(|e| rerr(e.to_string()))?;
    let layer = img.layer_data;
    let size = layer.size;
    let channels = layer
        .channel_data
        .list
        .iter()
        .map(|c| (c.name.to_string(), c.sample_data.values_as_f32().collect()))
        .collect();
    Ok((size.width() as u32, size.height() as u32, channels))
}

/// A linear RGB EXR (e.g. a reference image): width, height and the pixels, top row first.
pub fn read_exr(path: &Path) -> Result<(u32, u32, Vec<Vec3>), ReadError> {
    use exr::prelude::read_first_rgba_layer_from_file;
    check_exr_header(path, |_| 12).map_err(|message| ReadError {
        path: path.to_path_buf(),
        message,
    })?;
    let img = read_first_rgba_layer_from_file(
        path,
        |res, _| {
            let (w, h) = (res.width(), res.height());
            (w, h, vec![Vec3::ZERO; w * h])
        },
        |(w, _, data): &mut (usize, usize, Vec<Vec3>), pos, (r, g, b, _a): (f32, f32, f32, f32)| {
            data[pos.y() * *w + pos.x()] = Vec3::new(r, g, b);
        },
    )
    .map_err(|e| ReadError {
        path: path.to_path_buf(),
        message: e.to_string(),
    })?;
    let (w, h, data) = img.layer_data.channel_data.pixels;
    Ok((w as u32, h as u32, data))
}

/// An image file's width and height from its header alone (OpenEXR, Radiance HDR and the
/// formats `image` reads); `None` when it is not one.
pub fn image_dimensions(path: &Path) -> Option<(u32, u32)> {
    let is_exr = path
        .extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("exr"));
    if is_exr {
        let meta = exr::meta::MetaData::read_from_file(path, false).ok()?;
        let h = meta.headers.first()?;
        return Some((h.layer_size.width() as u32, h.layer_size.height() as u32));
    }
    image::ImageReader::open(path)
        .and_then(|r| r.with_guessed_format())
        .ok()?
        .into_dimensions()
        .ok()
}

/// Checks an EXR's header before its pixels are read (the `exr` crate allocates what the header
/// claims): the file must be a regular file, big enough to hold the offset table of every chunk
/// the header declares (8 bytes each, OpenEXR file layout), and the pixels as read
/// (`bytes_per_pixel` of the channel count) together with one block's buffer (a tile, or the
/// scan lines the compression groups) must fit in the load's memory budget: a small image may
/// declare tiles of 10⁹ × 10⁹ pixels, and the decoder allocates a whole tile.
fn check_exr_header(path: &Path, bytes_per_pixel: impl Fn(u64) -> u64) -> Result<(), String> {
    let file_len = std::fs::metadata(path)
        .map_err(|e| e.to_string())
        .and_then(|m| {
            if m.is_file() {
                Ok(m.len())
            } else {
                Err("is not a regular file".to_string())
            }
        })?;
    crate::limits::check_cancel()?;
    let meta = exr::meta::MetaData::read_from_file(path, false).map_err(|e| e.to_string())?;
    let mut chunks = 0u64;
    let mut bytes = 0u64;
    for h in &meta.headers {
        chunks = chunks.saturating_add(h.chunk_count as u64);
        let (w, ht) = (h.layer_size.width() as u64, h.layer_size.height() as u64);
        let channels = h.channels.list.len() as u64;
        let block = match h.blocks {
            exr::meta::BlockDescription::Tiles(t) => {
                (t.tile_size.width() as u64).saturating_mul(t.tile_size.height() as u64)
            }
            exr::meta::BlockDescription::ScanLines => {
                w.saturating_mul(h.compression.scan_lines_per_block() as u64)
            }
        };
        bytes = bytes.max(
            w.saturating_mul(ht)
                .saturating_add(block)
                .saturating_mul(bytes_per_pixel(channels.max(1))),
        );
    }
    if chunks.saturating_mul(8) > file_len {
        return Err(format!(
            "the header declares {chunks} chunks of pixels, more than a file of {file_len} bytes can hold"
        ));
    }
    let size = meta
        .headers
        .first()
        .map(|h| format!("{}×{}", h.layer_size.width(), h.layer_size.height()))
        .unwrap_or_default();
    crate::limits::charge(bytes, || format!("the {size} EXR image"))?;
    Ok(())
}

/// Reads any image an environment may be (EXR, Radiance HDR, PFM; PNG, TGA, JPEG as sRGB) into
/// linear RGB texels, top row first.
pub fn read_rgb(path: &Path) -> Result<(u32, u32, Vec<Vec3>), String> {
    let name = path.display().to_string();
    let lower = name.to_ascii_lowercase();
    if lower.ends_with(".exr") {
        let (w, h, data) = read_exr(path).map_err(|e| e.message)?;
        if w == 0 || h == 0 {
            return Err("environment map is empty".into());
        }
        return Ok((w, h, data));
    }
    let bytes =
        crate::limits::read_file(path).map_err(|e| format!("cannot read environment map: {e}"))?;
    let t = if lower.ends_with(".pfm") {
        decode_pfm(&name, &bytes)?
    } else {
        decode_texture(&name, &bytes, true)?
    };
    Ok((
        t.width,
        t.height,
        t.texels.iter().map(|c| c.truncate()).collect(),
    ))
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

    /// The float texels this module stored before texels were compact (kept here as the
    /// reference): 8-bit sRGB through a table of srgb_to_linear(i / 255), everything else through
    /// the image crate's f32 conversion, sRGB-decoded with powf.
    fn float_texels_as_before(img: &image::DynamicImage, srgb: bool) -> Vec<Vec4> {
        let hdr = matches!(
            img.color(),
            image::ColorType::Rgb32F | image::ColorType::Rgba32F
        );
        if !hdr && srgb && img.color().bytes_per_pixel() <= 4 {
            let lut: Vec<f32> = (0..256).map(|i| srgb_to_linear(i as f32 / 255.0)).collect();
            img.to_rgba8()
                .as_raw()
                .chunks_exact(4)
                .map(|p| {
                    let c = |v: u8| lut[v as usize];
                    Vec4::new(c(p[0]), c(p[1]), c(p[2]), p[3] as f32 / 255.0)
                })
                .collect()
        } else {
            let convert = srgb && !hdr;
            img.to_rgba32f()
                .as_raw()
                .chunks_exact(4)
                .map(|p| {
                    let c = |v: f32| if convert { srgb_to_linear(v) } else { v };
                    Vec4::new(c(p[0]), c(p[1]), c(p[2]), p[3])
                })
                .collect()
        }
    }

    /// Compact storage must not change a single lookup: every 8-bit code (and a spread of 16-bit
    /// ones) in every channel layout, sRGB and linear, read texel by texel and bilinearly at
    /// scattered points, equals the float storage bit for bit. Fails if a decode table entry,
    /// the 16-bit division or the alpha handling differs from the float path by one ulp.
    #[test]
    fn compact_texels_look_up_exactly_as_float_texels() {
        use crate::material::texture::Texels;
        let (w, h) = (64u32, 16u32); // 1024 texels: every 8-bit code four times
        let code8 = |i: u32, c: u32| ((i * 7 + c * 61) % 256) as u8;
        let code16 = |i: u32, c: u32| ((i * 4099 + c * 16411) % 65536) as u16;
        let images: Vec<image::DynamicImage> = vec![
            image::GrayImage::from_fn(w, h, |x, y| image::Luma([code8(y * w + x, 0)])).into(),
            image::GrayAlphaImage::from_fn(w, h, |x, y| {
                let i = y * w + x;
                image::LumaA([code8(i, 0), code8(i, 3)])
            })
            .into(),
            image::RgbImage::from_fn(w, h, |x, y| {
                let i = y * w + x;
                image::Rgb([code8(i, 0), code8(i, 1), code8(i, 2)])
            })
            .into(),
            image::RgbaImage::from_fn(w, h, |x, y| {
                let i = y * w + x;
                image::Rgba([code8(i, 0), code8(i, 1), code8(i, 2), code8(i, 3)])
            })
            .into(),
            image::ImageBuffer::<image::Luma<u16>, _>::from_fn(w, h, |x, y| {
                image::Luma([code16(y * w + x, 0)])
            })
            .into(),
            image::ImageBuffer::<image::LumaA<u16>, _>::from_fn(w, h, |x, y| {
                let i = y * w + x;
                image::LumaA([code16(i, 0), code16(i, 3)])
            })
            .into(),
            image::ImageBuffer::<image::Rgba<u16>, _>::from_fn(w, h, |x, y| {
                let i = y * w + x;
                image::Rgba([code16(i, 0), code16(i, 1), code16(i, 2), code16(i, 3)])
            })
            .into(),
            image::Rgb32FImage::from_fn(w, h, |x, y| {
                image::Rgb([(x as f32) * 0.37, y as f32 * 3.1, 1e-3])
            })
            .into(),
        ];
        let mut kinds = std::collections::BTreeSet::new();
        for img in &images {
            for srgb in [false, true] {
                let what = format!("{:?} srgb={srgb}", img.color());
                let t = texture_from_image("t", img, srgb).unwrap();
                kinds.insert(t.texels.kind());
                if img.color().bytes_per_pixel() / img.color().channel_count() == 1 {
                    assert_eq!(t.texels.bytes_per_texel(), 4, "{what}: 8-bit stays 8-bit");
                }
                let mut reference = t.clone();
                reference.texels = Texels::F32(float_texels_as_before(img, srgb));
                for i in 0..(w * h) as usize {
                    let (a, b) = (t.texels.get(i), reference.texels.get(i));
                    assert_eq!(
                        a.to_array().map(f32::to_bits),
                        b.to_array().map(f32::to_bits),
                        "{what}: texel {i}"
                    );
                }
                for k in 0..4096u32 {
                    // Points off the texel grid, some outside [0, 1] to exercise wrapping.
                    let uv = crate::math::Vec2::new(
                        (k as f32 * 0.618_034).fract() * 1.5 - 0.25,
                        (k as f32 * 0.754_877_7).fract() * 1.5 - 0.25,
                    );
                    let (a, b) = (t.lookup(uv), reference.lookup(uv));
                    assert_eq!(
                        a.to_array().map(f32::to_bits),
                        b.to_array().map(f32::to_bits),
                        "{what}: uv {uv}"
                    );
                }
            }
        }
        // Each storage kind was exercised (a silent fall back to float would pass the above).
        assert_eq!(
            kinds.into_iter().collect::<Vec<_>>(),
            ["f32", "srgb8", "unorm16", "unorm8", "unorm8-recip"]
        );
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
        assert!((s.texels.get(0).x - srgb_to_linear(128.0 / 255.0)).abs() < 1e-6);
        assert!((l.texels.get(0).x - 128.0 / 255.0).abs() < 1e-6);
        assert_eq!(s.texels.get(0).w, 1.0);
        assert!(decode_texture("t", b"not an image", true).is_err());
    }

    #[test]
    fn missing_file_gives_magenta_and_warning() {
        let mut w = Vec::new();
        let t = load_texture(Path::new("."), "no_such_texture.png", true, &mut w).unwrap();
        assert!(is_missing_texture(&t));
        assert_eq!(t.texels.get(0), MISSING_TEXTURE_COLOR);
        assert_eq!(w.len(), 1);
        assert!(w[0].contains("no_such_texture.png"));
        let mut w = Vec::new();
        assert!(load_texture(Path::new("."), "../x.png", true, &mut w).is_none());
        assert_eq!(w.len(), 1);
    }
}
