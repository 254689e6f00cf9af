//! Image files. The format follows the extension (docs/DESIGN.md §5): `.png` (8-bit sRGB after exposure and
//! tone mapping), `.ppm` (plain-text P3, as the thesis wrote, §5.1.2), `.exr` (linear 32-bit float,
//! the raw radiance) and `.hdr` (Radiance RGBE, linear). EXR and HDR ignore exposure and tone
//! mapping: they hold the estimate itself.

use super::Image;
use super::tonemap::Tonemap;
use std::io::Write;
use std::path::{Path, PathBuf};

#[derive(Debug, thiserror::Error)]
pub enum OutputError {
    #[error("{path}: unsupported output format (use .png, .ppm, .exr or .hdr)")]
    UnknownFormat { path: PathBuf },
    #[error("{path}: {message}")]
    Write { path: PathBuf, message: String },
    #[error("{path}: {message}")]
    Read { path: PathBuf, message: String },
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Format {
    Png,
    Ppm,
    Exr,
    Hdr,
}

impl Format {
    pub fn from_path(path: &Path) -> Result<Format, OutputError> {
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .map(|e| e.to_ascii_lowercase());
        match ext.as_deref() {
            Some("png") => Ok(Format::Png),
            Some("ppm") => Ok(Format::Ppm),
            Some("exr") => Ok(Format::Exr),
            Some("hdr") => Ok(Format::Hdr),
            _ => Err(OutputError::UnknownFormat {
                path: path.to_path_buf(),
            }),
        }
    }
}

/// Display-referred 8-bit RGB after exposure and tone mapping.
pub fn to_rgb8(image: &Image, exposure: f32, tonemap: Tonemap) -> Vec<u8> {
    let mut out = Vec::with_capacity(image.data.len() * 3);
    for p in &image.data {
        let c = tonemap.apply(*p * exposure);
        for v in [c.x, c.y, c.z] {
            out.push((v * 255.0 + 0.5).clamp(0.0, 255.0) as u8);
        }
    }
    out
}

/// Writes `image`, premultiplied by the coverage `alpha` (one value per pixel), as an RGBA PNG.
/// PNG stores straight (unassociated) alpha, so each colour is divided by its alpha before the
/// view transform (a tone curve applied to premultiplied values would darken the edges twice).
pub fn write_png_rgba(
    image: &Image,
    alpha: &[f32],
    path: &Path,
    exposure: f32,
    tonemap: Tonemap,
) -> Result<(), OutputError> {
    let mut out = Vec::with_capacity(image.data.len() * 4);
    for (p, &a) in image.data.iter().zip(alpha) {
        let a = if a.is_finite() {
            a.clamp(0.0, 1.0)
        } else {
            0.0
        };
        let straight = if a > 0.0 {
            *p / a
        } else {
            crate::math::Vec3::ZERO
        };
        let c = tonemap.apply(straight * exposure);
        for v in [c.x, c.y, c.z, a] {
            out.push((v * 255.0 + 0.5).clamp(0.0, 255.0) as u8);
        }
    }
    image::save_buffer_with_format(
        path,
        &out,
        image.width,
        image.height,
        image::ExtendedColorType::Rgba8,
        image::ImageFormat::Png,
    )
    .map_err(|e| OutputError::Write {
        path: path.to_path_buf(),
        message: e.to_string(),
    })
}

/// Writes `image` to `path` in the format its extension names.
pub fn write_image(
    image: &Image,
    path: &Path,
    exposure: f32,
    tonemap: Tonemap,
) -> Result<(), OutputError> {
    let format = Format::from_path(path)?;
    let werr = |m: String| OutputError::Write {
        path: path.to_path_buf(),
        message: m,
    };
    match format {
        Format::Png => {
            let rgb = to_rgb8(image, exposure, tonemap);
            image::save_buffer_with_format(
                path,
                &rgb,
                image.width,
                image.height,
                image::ExtendedColorType::Rgb8,
                image::ImageFormat::Png,
            )
            .map_err(|e| werr(e.to_string()))
        }
        Format::Ppm => {
            let rgb = to_rgb8(image, exposure, tonemap);
            let mut text = String::with_capacity(rgb.len() * 4 + 32);
            text.push_str(&format!("P3\n{} {}\n255\n", image.width, image.height));
            for row in rgb.chunks(image.width as usize * 3) {
                let line: Vec<String> = row.iter().map(|v| v.to_string()).collect();
                text.push_str(&line.join(" "));
                text.push('\n');
            }
            std::fs::File::create(path)
                .and_then(|mut f| f.write_all(text.as_bytes()))
                .map_err(|e| werr(e.to_string()))
        }
        Format::Exr => {
            use exr::prelude::*;
            let w = image.width as usize;
            let channels = SpecificChannels::rgb(|pos: Vec2<usize>| {
                let p = image.data[pos.y() * w + pos.x()];
                (p.x, p.y, p.z)
            });
            // Blocks written in order (not in the order parallel compression finishes them), so
            // the same image always gives the same bytes: renders can be compared with `cmp`.
            Image::from_channels((w, image.height as usize), channels)
                .write()
                .non_parallel()
                .to_file(path)
                .map_err(|e| werr(e.to_string()))
        }
        Format::Hdr => {
            let pixels: Vec<image::Rgb<f32>> = image
                .data
                .iter()
                .map(|p| image::Rgb([rgbe_safe(p.x), rgbe_safe(p.y), rgbe_safe(p.z)]))
                .collect();
            let file = std::fs::File::create(path).map_err(|e| werr(e.to_string()))?;
            image::codecs::hdr::HdrEncoder::new(std::io::BufWriter::new(file))
                .encode(&pixels, image.width as usize, image.height as usize)
                .map_err(|e| werr(e.to_string()))
        }
    }
}

/// A value Radiance RGBE can hold: it has no sign, NaN or infinity (the image crate's encoder
/// overflows on an infinite value), so those become 0 or the largest representable magnitude
/// (2^127 ≈ 1.7e38 needs the top exponent; 1e38 is safely inside it).
fn rgbe_safe(v: f32) -> f32 {
    if v.is_nan() || v <= 0.0 {
        0.0
    } else {
        v.min(1e38)
    }
}

/// Writes `image` (channels `R G B`) and `layers` (their own channel names, see
/// [`super::aov`]) into one single-part EXR of 32-bit float channels: the layout of Blender's
/// multi-layer EXR, which OpenImageIO, Nuke and Blender read as layers. Blocks are written in
/// order, so the same input always gives the same bytes.
pub fn write_exr_layers(
    image: &Image,
    layers: &[super::aov::Layer],
    path: &Path,
) -> Result<(), OutputError> {
    use exr::prelude::*;
    let werr = |m: String| OutputError::Write {
        path: path.to_path_buf(),
        message: m,
    };
    let (w, h) = (image.width as usize, image.height as usize);
    let mut channels: Vec<AnyChannel<FlatSamples>> = Vec::new();
    for (c, name) in ["R", "G", "B"].into_iter().enumerate() {
        let v = image.data.iter().map(|p| p[c]).collect();
        channels.push(AnyChannel::new(name, FlatSamples::F32(v)));
    }
    for l in layers {
        if (l.width as usize, l.height as usize) != (w, h) {
            return Err(werr(format!(
                "layer {} is {}x{}, the image {w}x{h}",
                l.name, l.width, l.height
            )));
        }
        let d = l.depth();
        for (c, name) in l.channels.iter().enumerate() {
            let v = l.data.iter().skip(c).step_by(d).copied().collect();
            channels.push(AnyChannel::new(name.as_str(), FlatSamples::F32(v)));
        }
    }
    let mut names: Vec<&Text> = channels.iter().map(|c| &c.name).collect();
    names.sort();
    if names.windows(2).any(|p| p[0] == p[1]) {
        return Err(werr("two layers have the same channel name".into()));
    }
    let layer = Layer::new(
        (w, h),
        LayerAttributes::default(),
        Encoding::SMALL_LOSSLESS,
        AnyChannels::sort(SmallVec::from_vec(channels)),
    );
    Image::from_layer(layer)
        .write()
        .non_parallel()
        .to_file(path)
        .map_err(|e| werr(e.to_string()))
}

pub use crate::image_io::ExrChannels;

/// Every channel of a single-part EXR by name ([`crate::image_io::read_exr_channels`]).
pub fn read_exr_channels(path: &Path) -> Result<ExrChannels, OutputError> {
    crate::image_io::read_exr_channels(path).map_err(OutputError::from)
}

/// Reads a linear RGB EXR (e.g. a reference image) ([`crate::image_io::read_exr`]).
pub fn read_exr(path: &Path) -> Result<Image, OutputError> {
    let (width, height, data) = crate::image_io::read_exr(path)?;
    Ok(Image {
        width,
        height,
        data,
    })
}

impl From<crate::image_io::ReadError> for OutputError {
    fn from(e: crate::image_io::ReadError) -> OutputError {
        OutputError::Read {
            path: e.path,
            message: e.message,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Vec3;

    fn gradient() -> Image {
        let (w, h) = (8u32, 4u32);
        let data = (0..w * h)
            .map(|i| Vec3::new(i as f32 / 32.0, 0.25, 2.0))
            .collect();
        Image {
            width: w,
            height: h,
            data,
        }
    }

    #[test]
    fn exr_round_trips_exactly() {
        let dir = tempdir();
        let p = dir.join("a.exr");
        let img = gradient();
        write_image(&img, &p, 1.0, Tonemap::Clamp).unwrap();
        let back = read_exr(&p).unwrap();
        assert_eq!(back, img);
    }

    #[test]
    fn ppm_is_plain_p3() {
        let dir = tempdir();
        let p = dir.join("a.ppm");
        write_image(&gradient(), &p, 1.0, Tonemap::Gamma22).unwrap();
        let text = std::fs::read_to_string(&p).unwrap();
        let mut it = text.split_whitespace();
        assert_eq!(it.next(), Some("P3"));
        assert_eq!(it.next(), Some("8"));
        assert_eq!(it.next(), Some("4"));
        assert_eq!(it.next(), Some("255"));
        assert_eq!(it.count(), 8 * 4 * 3);
    }

    #[test]
    fn hdr_output_survives_values_rgbe_cannot_hold() {
        let dir = std::env::temp_dir().join(format!("trayecto_hdr_inf_{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let mut img = gradient();
        img.data[0] = Vec3::new(f32::INFINITY, f32::NAN, -1.0);
        img.data[1] = Vec3::new(f32::MAX, 0.0, 0.0);
        write_image(&img, &dir.join("inf.hdr"), 1.0, Tonemap::Clamp).unwrap();
        let back = image::open(dir.join("inf.hdr")).unwrap().to_rgb32f();
        let p = back.get_pixel(0, 0);
        assert!(p[0] > 1e37 && p[1] == 0.0 && p[2] == 0.0, "{p:?}");
        // RGBE shares one exponent per pixel: f32::MAX is clamped, not overflowed.
        assert!(back.get_pixel(1, 0)[0] > 1e37);
        // The other pixels are untouched.
        assert!((back.get_pixel(2, 0)[1] - 0.25).abs() < 0.01);
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn png_and_hdr_write_and_unknown_extension_fails() {
        let dir = tempdir();
        write_image(&gradient(), &dir.join("a.png"), 1.0, Tonemap::Clamp).unwrap();
        let png = image::open(dir.join("a.png")).unwrap();
        assert_eq!((png.width(), png.height()), (8, 4));
        write_image(&gradient(), &dir.join("a.hdr"), 1.0, Tonemap::Clamp).unwrap();
        let hdr = image::open(dir.join("a.hdr")).unwrap().to_rgb32f();
        assert!((hdr.get_pixel(0, 0)[2] - 2.0).abs() < 0.02);
        assert!(matches!(
            write_image(&gradient(), &dir.join("a.bmp"), 1.0, Tonemap::Clamp),
            Err(OutputError::UnknownFormat { .. })
        ));
    }

    /// Radiance from 0 to ~3 across x, different per channel and per row (so a transposed,
    /// flipped or channel-swapped writer is caught).
    fn ramp() -> Image {
        let (w, h) = (16u32, 6u32);
        let data = (0..w * h)
            .map(|i| {
                let (x, y) = ((i % w) as f32, (i / w) as f32);
                Vec3::new(
                    x * 0.2 * (1.0 + y * 0.1),
                    0.05 * y + 0.01 * x,
                    3.0 - x * 0.19,
                )
            })
            .collect();
        Image {
            width: w,
            height: h,
            data,
        }
    }

    /// The display value expected from each curve, written out here (not via `Tonemap::apply`)
    /// for the two simple ones; ACES and AgX are pinned to their published curves in tonemap.rs.
    fn expected_display(tonemap: Tonemap, l: f32) -> f32 {
        let srgb = |c: f32| {
            if c <= 0.0031308 {
                12.92 * c
            } else {
                1.055 * c.powf(1.0 / 2.4) - 0.055
            }
        };
        match tonemap {
            Tonemap::Clamp => srgb(l.clamp(0.0, 1.0)),
            Tonemap::Gamma22 => l.clamp(0.0, 1.0).powf(1.0 / 2.2),
            other => other.apply(Vec3::splat(l)).x,
        }
    }

    /// PNG and PPM decode to round(255 · tonemap(exposure · L)) per pixel and channel (±1 for the
    /// rounding of values that land on a half step), rows top first.
    #[test]
    fn png_and_ppm_hold_the_tone_mapped_exposed_radiance() {
        let dir = tempdir();
        let img = ramp();
        for (tonemap, exposure) in [
            (Tonemap::Clamp, 1.0),
            (Tonemap::Clamp, 0.37),
            (Tonemap::Gamma22, 1.6),
            (Tonemap::Aces, 2.5),
            (Tonemap::Agx, 0.8),
        ] {
            let (png, ppm) = (dir.join("t.png"), dir.join("t.ppm"));
            write_image(&img, &png, exposure, tonemap).unwrap();
            write_image(&img, &ppm, exposure, tonemap).unwrap();
            let png = image::open(&png).unwrap().to_rgb8();
            assert_eq!((png.width(), png.height()), (img.width, img.height));
            let text = std::fs::read_to_string(&ppm).unwrap();
            let ppm: Vec<u32> = text
                .split_whitespace()
                .skip(4)
                .map(|v| v.parse().unwrap())
                .collect();
            assert_eq!(ppm.len(), (img.width * img.height * 3) as usize);
            for y in 0..img.height {
                for x in 0..img.width {
                    let l = img.data[(y * img.width + x) as usize] * exposure;
                    for c in 0..3 {
                        let want = if matches!(tonemap, Tonemap::Agx) {
                            // AgX mixes channels: the whole colour through the curve.
                            tonemap.apply(l)[c]
                        } else {
                            expected_display(tonemap, l[c])
                        };
                        let want = (want * 255.0).round() as i32;
                        let got_png = png.get_pixel(x, y)[c] as i32;
                        let got_ppm = ppm[((y * img.width + x) * 3) as usize + c] as i32;
                        for (what, got) in [("PNG", got_png), ("PPM", got_ppm)] {
                            assert!(
                                (got - want).abs() <= 1,
                                "{what} {tonemap:?} exposure {exposure} pixel ({x}, {y}) channel {c}: {got}, expected {want}"
                            );
                        }
                    }
                }
            }
        }
    }

    /// EXR and HDR carry the raw radiance: exposure and tone mapping do not touch them.
    #[test]
    fn exr_and_hdr_hold_the_raw_radiance_and_ignore_exposure() {
        let dir = tempdir();
        let img = ramp();
        let (exr, hdr) = (dir.join("raw.exr"), dir.join("raw.hdr"));
        write_image(&img, &exr, 3.5, Tonemap::Aces).unwrap();
        write_image(&img, &hdr, 3.5, Tonemap::Agx).unwrap();
        assert_eq!(read_exr(&exr).unwrap(), img);
        let back = image::open(&hdr).unwrap().to_rgb32f();
        assert_eq!((back.width(), back.height()), (img.width, img.height));
        for y in 0..img.height {
            for x in 0..img.width {
                let l = img.data[(y * img.width + x) as usize];
                let p = back.get_pixel(x, y);
                // RGBE: 8-bit mantissas under the largest channel's exponent.
                let tol = l.max_element() / 128.0;
                for c in 0..3 {
                    assert!(
                        (p[c] - l[c]).abs() <= tol,
                        "HDR pixel ({x}, {y}) channel {c}: {}, radiance {}",
                        p[c],
                        l[c]
                    );
                }
            }
        }
    }

    fn tempdir() -> PathBuf {
        let d = std::env::temp_dir().join(format!(
            "trayecto-out-{}-{:?}",
            std::process::id(),
            std::thread::current().id()
        ));
        std::fs::create_dir_all(&d).unwrap();
        d
    }
}
