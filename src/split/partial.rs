//! Partial films (`.trp`): the exact accumulators of sample indices `start..end` of a frame, with a
//! header saying which frame they belong to, so parts rendered apart (other processes, other
//! machines, a render stopped and resumed) can be checked and merged into the image a single run
//! gives, bit for bit.
//!
//! Layout (all integers little-endian):
//!
//! | bytes | content |
//! |---|---|
//! | 8 | magic `TRAYPART` |
//! | 4 | `u32` length `L` of the header (at most [`MAX_HEADER`]) |
//! | `L` | the header, JSON ([`PartHeader`]) |
//! | rest | a zlib stream (RFC 1950, with its Adler-32 check) of: `width·height` pixels × 3 channels of `i128` fixed-point sums (row-major, top row first, RGB; value = sum · 2^-`frac_bits`), then `width·height` `u32` sample counts, then, when the header says `coverage` (a `--transparent` render), `width·height` `u32` counts of the samples whose camera ray hit geometry (the alpha channel's numerators) |
//!
//! The header names the scene by content (a SHA-256 of the scene file's bytes and of everything
//! the loader read from it, see [`crate::scene::digest`]), lists every setting that changes the
//! image, the image size, the frame's samples per pixel, the sample range it holds, the fixed-point
//! format, the Trayecto version and the render identity ([`crate::RENDER_IDENTITY`], a hash of the
//! sources of the build). Reading checks everything a hostile or truncated file could get
//! wrong before allocating, and that every sum is within what its count of samples can reach.

use crate::film::{FRAC_BITS, Film, SAMPLE_LIMIT};
use crate::render::{MAX_DIMENSION, MAX_PIXELS, MAX_SPP, RenderSettings};
use crate::world::WorldOptions;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::io::{Read, Write};
use std::path::{Path, PathBuf};

pub const MAGIC: &[u8; 8] = b"TRAYPART";
/// 2 added `render_identity` and the resolved `light_sampler` setting; format-1 parts (which
/// have neither) are refused with a message saying to render them again.
pub const FORMAT_VERSION: u32 = 2;
pub const MAX_HEADER: u32 = 1 << 20;

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PartHeader {
    /// [`FORMAT_VERSION`].
    pub format: u32,
    /// `CARGO_PKG_VERSION` of the Trayecto that rendered it.
    pub trayecto_version: String,
    /// [`crate::RENDER_IDENTITY`] of the build that rendered it: two builds of one version can
    /// render different images, so parts merge only when this matches. Empty when absent (a
    /// format-1 part, refused by [`Part::read`] before anything else is checked).
    #[serde(default)]
    pub render_identity: String,
    /// The scene as it was named on the command line (for messages only: machines may see the
    /// same scene at different paths).
    pub scene: String,
    /// SHA-256 (hex) of the scene's content, see [`crate::scene::digest`].
    pub scene_digest: String,
    /// Every setting that changes the image, by name (see [`image_settings`]).
    pub settings: BTreeMap<String, String>,
    pub width: u32,
    pub height: u32,
    /// Samples per pixel of the whole frame.
    pub spp: u32,
    /// The sample indices held: `samples[0]..samples[1]`.
    pub samples: [u32; 2],
    /// Fraction bits of the fixed-point sums.
    pub frac_bits: u32,
    /// Samples discarded as NaN, infinite or beyond the sample limit.
    pub discarded: u64,
    /// The pixel data ends with coverage counts (`--transparent`: the alpha channel). Absent
    /// (false) from the headers of opaque renders, which are therefore unchanged.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub coverage: bool,
}

/// A partial film read back or about to be written.
#[derive(Clone, Debug)]
pub struct Part {
    pub header: PartHeader,
    pub film: Film,
}

#[derive(Debug, thiserror::Error)]
pub enum PartError {
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("{path}: not a Trayecto partial film: {message}")]
    Format { path: PathBuf, message: String },
    #[error("{0}")]
    Merge(String),
}

fn format_err(path: &Path, message: impl Into<String>) -> PartError {
    PartError::Format {
        path: path.to_path_buf(),
        message: message.into(),
    }
}

/// The settings that change the image, as name → value strings: every field of the
/// [`RenderSettings`] and [`WorldOptions`] the renderer is given, each as its `Debug` text (floats
/// in Rust's shortest round-trip form, so equal strings mean equal values; nested settings such as
/// the path tracer's or the filter's show every field they have). Both structs are destructured
/// field by field below, so a new setting does not compile until it is listed here: it is compared
/// unless it is left out on purpose, with the reason. Left out: the thread count (the image does
/// not depend on it), whether squared sums are tracked (the beauty film is the same) and the
/// environment map's path (machines may mount it elsewhere; its content is in the scene digest).
/// `light_sampler` is the sampler the built world uses ([`crate::light::LightSet::sampler_kind`]),
/// never `auto`: `auto` resolves to different samplers by light count and version.
pub fn image_settings(
    s: &RenderSettings,
    w: &WorldOptions,
    light_sampler: crate::light::LightSamplerKind,
) -> BTreeMap<String, String> {
    debug_assert!(
        light_sampler != crate::light::LightSamplerKind::Auto,
        "image_settings wants the resolved light sampler"
    );
    let RenderSettings {
        width,
        height,
        spp,
        seed,
        threads: _,
        sampler,
        integrator,
        path,
        filter,
        noise_threshold,
        time_limit,
        crop,
        track_variance: _,
        // Whether the pixels end with coverage counts: the header's `coverage`.
        track_coverage: _,
        guiding,
        photon,
        mlt,
    } = s;
    let WorldOptions {
        accel,
        camera,
        default_light,
        env,
        env_rotation,
        camera_override,
        variant,
        light_sampler: _,
        texture_filter,
        instancing,
        time,
    } = w;
    let env_map = env.is_some();
    let light_sampler = light_sampler.name();
    let fields: [(&str, &dyn std::fmt::Debug); 22] = [
        ("width", width),
        ("height", height),
        ("spp", spp),
        ("seed", seed),
        ("sampler", sampler),
        ("integrator", integrator),
        ("path", path),
        ("filter", filter),
        ("noise_threshold", noise_threshold),
        ("time_limit", time_limit),
        ("crop", crop),
        ("accel", accel),
        ("camera", camera),
        ("default_light", default_light),
        ("env_map", &env_map),
        ("env_rotation", env_rotation),
        ("camera_view", camera_override),
        ("variant", variant),
        ("texture_filter", texture_filter),
        // Instanced and flattened renders agree bit for bit, but the object-id AOV numbers
        // instances after the analytic shapes.
        ("instancing", instancing),
        // The moment and the shutter: frames of an animation are different images.
        ("time", time),
        // The photon integrators' photons per iteration and radius.
        ("photon", photon),
    ];
    let mut m: BTreeMap<String, String> = fields
        .iter()
        .map(|(k, v)| (k.to_string(), format!("{v:?}")))
        .collect();
    m.insert("light_sampler".into(), light_sampler.to_string());
    // Only when on, so that the headers of unguided parts are unchanged.
    if *guiding {
        m.insert("guiding".into(), "true".into());
    }
    // Only for Metropolis light transport, which reads them (other parts' headers unchanged).
    if *integrator == crate::integrator::IntegratorKind::Mlt {
        m.insert("mlt".into(), format!("{mlt:?}"));
    }
    m
}

/// Whether a part's pixels each hold every sample of its range that was not discarded: true
/// unless it comes from an adaptive render (whose converged pixels stopped early; such a film is
/// only ever saved when writing its image failed, see [`crate::pipeline`]).
fn uniform_counts(h: &PartHeader) -> bool {
    h.settings
        .get("noise_threshold")
        .is_none_or(|v| v == "None")
}

/// Where two `Debug` texts first differ, as the comma-separated pieces around it (`max_depth:
/// 5` rather than two whole structs).
fn first_difference(a: &str, b: &str) -> (String, String) {
    let split = |s: &str| -> Vec<String> {
        s.split([',', '{', '}', '(', ')'])
            .map(|p| p.trim().to_string())
            .collect()
    };
    let (pa, pb) = (split(a), split(b));
    match pa.iter().zip(&pb).find(|(x, y)| x != y) {
        Some((x, y)) if !x.is_empty() && !y.is_empty() => (x.clone(), y.clone()),
        _ => (a.to_string(), b.to_string()),
    }
}

impl PartHeader {
    /// The header of the part `samples` of a frame, rendered with the light sampler
    /// `light_sampler` (resolved: the built world's [`crate::light::LightSet::sampler_kind`]).
    pub fn new(
        scene: &str,
        scene_digest: &str,
        settings: &RenderSettings,
        world: &WorldOptions,
        light_sampler: crate::light::LightSamplerKind,
        samples: [u32; 2],
        discarded: u64,
    ) -> PartHeader {
        PartHeader {
            format: FORMAT_VERSION,
            trayecto_version: env!("CARGO_PKG_VERSION").to_string(),
            render_identity: crate::RENDER_IDENTITY.to_string(),
            scene: scene.to_string(),
            scene_digest: scene_digest.to_string(),
            settings: image_settings(settings, world, light_sampler),
            // The film's size: the crop window's when cropped (the window itself is a setting).
            width: settings.film_window().width(),
            height: settings.film_window().height(),
            spp: settings.spp,
            samples,
            frac_bits: FRAC_BITS,
            discarded,
            coverage: settings.counts_coverage(),
        }
    }

    /// Why `other` does not belong to the same frame as `self`, if it does not: the first field
    /// that differs, with both values.
    pub fn mismatch(&self, other: &PartHeader) -> Option<String> {
        let diff = |what: &str, a: &dyn std::fmt::Display, b: &dyn std::fmt::Display| {
            Some(format!("{what} is {b} there but {a} here"))
        };
        if self.trayecto_version != other.trayecto_version {
            return diff(
                "the Trayecto version",
                &self.trayecto_version,
                &other.trayecto_version,
            );
        }
        if self.render_identity != other.render_identity {
            let short = |s: &str| s[..s.len().min(16)].to_string();
            return Some(format!(
                "it was rendered by another build (render identity {} there but {} here): builds \
                 of the same version can render different images, so render every part with one \
                 binary",
                short(&other.render_identity),
                short(&self.render_identity)
            ));
        }
        if self.scene_digest != other.scene_digest {
            return Some(format!(
                "the scene content differs ('{}' there, '{}' here; digests {} and {})",
                other.scene,
                self.scene,
                &other.scene_digest[..other.scene_digest.len().min(12)],
                &self.scene_digest[..self.scene_digest.len().min(12)]
            ));
        }
        if (self.width, self.height) != (other.width, other.height) {
            return diff(
                "the image size",
                &format!("{}x{}", self.width, self.height),
                &format!("{}x{}", other.width, other.height),
            );
        }
        if self.spp != other.spp {
            return diff("the frame's samples per pixel", &self.spp, &other.spp);
        }
        if self.frac_bits != other.frac_bits {
            return diff("the fixed-point format", &self.frac_bits, &other.frac_bits);
        }
        let keys: std::collections::BTreeSet<&String> =
            self.settings.keys().chain(other.settings.keys()).collect();
        for k in keys {
            let (a, b) = (self.settings.get(k), other.settings.get(k));
            if a != b {
                let show = |v: Option<&String>| v.cloned().unwrap_or_else(|| "unset".into());
                let (a, b) = first_difference(&show(a), &show(b));
                return diff(&format!("the setting '{k}'"), &a, &b);
            }
        }
        None
    }
}

impl Part {
    /// Writes the part to `path` atomically: to a temporary file beside it, flushed to disk, then
    /// renamed over `path`, so a crash leaves either the old file or the new one, never half.
    pub fn write(&self, path: &Path) -> Result<(), PartError> {
        write_film(&self.header, &self.film, path)
    }

    /// Reads and checks a part: [`PartFile::open`], then [`PartFile::read`].
    pub fn read(path: &Path) -> Result<Part, PartError> {
        PartFile::open(path)?.read()
    }
}

/// [`Part::write`] of a film under a header, without making them a [`Part`] (no copy of the film).
pub fn write_film(header: &PartHeader, film: &Film, path: &Path) -> Result<(), PartError> {
    let io = |source| PartError::Io {
        path: path.to_path_buf(),
        source,
    };
    let mut name = path.file_name().unwrap_or_default().to_os_string();
    name.push(format!(".tmp{}", std::process::id()));
    let tmp = path.with_file_name(name);
    let result = (|| {
        let file = std::fs::File::create(&tmp)?;
        let mut out = std::io::BufWriter::new(file);
        let json = serde_json::to_vec(header).map_err(std::io::Error::other)?;
        out.write_all(MAGIC)?;
        out.write_all(&(json.len() as u32).to_le_bytes())?;
        out.write_all(&json)?;
        let mut z = flate2::write::ZlibEncoder::new(out, flate2::Compression::fast());
        let (sum, count) = film.raw();
        let mut buf = Vec::with_capacity(48 * 1024);
        for s in sum {
            for c in s {
                buf.extend_from_slice(&c.to_le_bytes());
            }
            if buf.len() >= 48 * 1024 {
                z.write_all(&buf)?;
                buf.clear();
            }
        }
        let coverage = match (header.coverage, film.coverage()) {
            (false, _) => &[][..],
            (true, Some(c)) => c,
            (true, None) => {
                return Err(std::io::Error::other(
                    "the header promises coverage (alpha) the film does not hold",
                ));
            }
        };
        for n in count.iter().chain(coverage) {
            buf.extend_from_slice(&n.to_le_bytes());
            if buf.len() >= 48 * 1024 {
                z.write_all(&buf)?;
                buf.clear();
            }
        }
        z.write_all(&buf)?;
        let out = z.finish()?;
        let file = out.into_inner().map_err(|e| e.into_error())?;
        file.sync_all()?;
        std::fs::rename(&tmp, path)
    })();
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result.map_err(io)
}

/// Deflate's largest compression ratio (a 258-byte match in two bits, RFC 1951): a zlib stream
/// of `n` bytes cannot unpack to more than about this many times `n`.
const MAX_DEFLATE_RATIO: u64 = 1032;

/// Bytes of pixel data per pixel once unpacked: three `i128` sums and a `u32` count, and a `u32`
/// coverage count when the header says so.
fn pixel_bytes(h: &PartHeader) -> u64 {
    48 + 4 + if h.coverage { 4 } else { 0 }
}

/// A partial film whose header has been read and checked, its pixels not yet: what a merge or
/// a resume looks at first, so that parts of another frame are refused before any pixel memory
/// is allocated.
pub struct PartFile {
    pub path: PathBuf,
    pub header: PartHeader,
    /// Where the zlib stream of the pixels starts, and how many bytes the file has after it.
    data_start: u64,
    data_len: u64,
}

impl PartFile {
    /// Reads and checks the header: format, size, sample range, and that the rest of the file
    /// is large enough to hold the pixels the header claims.
    pub fn open(path: &Path) -> Result<PartFile, PartError> {
        let io = |source| PartError::Io {
            path: path.to_path_buf(),
            source,
        };
        let file = std::fs::File::open(path).map_err(io)?;
        let meta = file.metadata().map_err(io)?;
        if !meta.is_file() {
            return Err(format_err(path, "it is not a regular file"));
        }
        let mut r = std::io::BufReader::new(file);
        let mut magic = [0u8; 8];
        r.read_exact(&mut magic)
            .map_err(|_| format_err(path, "the file is too short"))?;
        if &magic != MAGIC {
            return Err(format_err(path, "it does not start with TRAYPART"));
        }
        let mut len = [0u8; 4];
        r.read_exact(&mut len)
            .map_err(|_| format_err(path, "the file is too short"))?;
        let len = u32::from_le_bytes(len);
        if len > MAX_HEADER {
            return Err(format_err(
                path,
                format!("the header is {len} bytes (at most {MAX_HEADER})"),
            ));
        }
        let mut hbytes = vec![0u8; len as usize];
        r.read_exact(&mut hbytes)
            .map_err(|_| format_err(path, "the header is truncated"))?;
        let h: PartHeader = serde_json::from_slice(&hbytes)
            .map_err(|e| format_err(path, format!("bad header: {e}")))?;
        if h.format == 1 {
            return Err(format_err(
                path,
                format!(
                    "format version 1, from a Trayecto before render identities: it does not say \
                     which build rendered it, so it cannot be merged safely; render it again \
                     (this Trayecto reads format {FORMAT_VERSION})"
                ),
            ));
        }
        if h.format != FORMAT_VERSION {
            return Err(format_err(
                path,
                format!(
                    "format version {} (this Trayecto reads {FORMAT_VERSION})",
                    h.format
                ),
            ));
        }
        if h.frac_bits != FRAC_BITS {
            return Err(format_err(
                path,
                format!(
                    "fixed-point sums with {} fraction bits (expected {FRAC_BITS})",
                    h.frac_bits
                ),
            ));
        }
        let pixels = h.width as u64 * h.height as u64;
        if h.width == 0
            || h.height == 0
            || h.width > MAX_DIMENSION
            || h.height > MAX_DIMENSION
            || pixels > MAX_PIXELS
        {
            return Err(format_err(
                path,
                format!("image size {}x{} is out of range", h.width, h.height),
            ));
        }
        let [a, b] = h.samples;
        if h.spp == 0 || h.spp > MAX_SPP || !(a < b && b <= h.spp) {
            return Err(format_err(
                path,
                format!("sample range {a}..{b} of a {}-spp frame is invalid", h.spp),
            ));
        }
        let data_start = 12 + len as u64;
        let data_len = meta.len().saturating_sub(data_start);
        let expected = pixels * pixel_bytes(&h);
        if expected > data_len.saturating_mul(MAX_DEFLATE_RATIO) {
            return Err(format_err(
                path,
                format!(
                    "its header claims {}x{} pixels ({expected} bytes of sums and counts), more \
                     than the {data_len} bytes after it can hold (zlib packs at most \
                     {MAX_DEFLATE_RATIO}:1): the file is truncated or forged",
                    h.width, h.height
                ),
            ));
        }
        Ok(PartFile {
            path: path.to_path_buf(),
            header: h,
            data_start,
            data_len,
        })
    }

    /// The pixel data, unpacked: exactly the expected number of bytes are let through (one more
    /// is asked for, to see whether the stream goes on: no zip bombs).
    fn pixel_stream(&self) -> Result<impl Read, PartError> {
        use std::io::Seek;
        let io = |source| PartError::Io {
            path: self.path.clone(),
            source,
        };
        let mut file = std::fs::File::open(&self.path).map_err(io)?;
        file.seek(std::io::SeekFrom::Start(self.data_start))
            .map_err(io)?;
        let n = self.header.width as u64 * self.header.height as u64;
        let z = flate2::read::ZlibDecoder::new(std::io::BufReader::new(file.take(self.data_len)));
        Ok(z.take(n * pixel_bytes(&self.header) + 1))
    }

    /// Reads the pixels, checked twice: a first pass over the stream, holding nothing, checks
    /// its length and that the sample counts agree with the header (each at most the range's
    /// length, and the samples missing from them exactly the ones the header says were
    /// discarded: every sample of a fixed-count render is either counted in its pixel or
    /// discarded); only then are the arrays allocated, at their exact size, and filled by a
    /// second pass, which checks every sum against what its count of samples can reach. A
    /// forged file therefore costs the time to unpack it, never the memory its header asks for.
    pub fn read(self) -> Result<Part, PartError> {
        let h = &self.header;
        let path = self.path.as_path();
        let n = h.width as usize * h.height as usize;
        let span = h.samples[1] - h.samples[0];
        let short = |_| format_err(path, "the pixel data is truncated or corrupt");

        // First pass: lengths and counts, nothing kept.
        let mut z = self.pixel_stream()?;
        let mut buf = vec![0u8; 1 << 16];
        let mut sums_left = n as u64 * 48;
        while sums_left > 0 {
            let k = sums_left.min(buf.len() as u64) as usize;
            z.read_exact(&mut buf[..k]).map_err(short)?;
            sums_left -= k as u64;
        }
        let mut missing = 0u64;
        let mut counts_left = n;
        while counts_left > 0 {
            let k = counts_left.min(buf.len() / 4);
            z.read_exact(&mut buf[..4 * k]).map_err(short)?;
            for (i, w) in buf[..4 * k].chunks_exact(4).enumerate() {
                let c = u32::from_le_bytes([w[0], w[1], w[2], w[3]]);
                if c > span {
                    let p = (n - counts_left + i) as u64;
                    return Err(format_err(
                        path,
                        format!(
                            "pixel ({}, {}) holds impossible values: {c} samples, more than \
                             its range of {span}",
                            p % h.width as u64,
                            p / h.width as u64
                        ),
                    ));
                }
                missing += (span - c) as u64;
            }
            counts_left -= k;
        }
        // Coverage: never more covered samples than the range holds (checked against the
        // pixel's own count once both are read).
        let mut cover_left = if h.coverage { n } else { 0 };
        while cover_left > 0 {
            let k = cover_left.min(buf.len() / 4);
            z.read_exact(&mut buf[..4 * k]).map_err(short)?;
            if let Some(i) = buf[..4 * k]
                .chunks_exact(4)
                .position(|w| u32::from_le_bytes([w[0], w[1], w[2], w[3]]) > span)
            {
                let p = (n - cover_left + i) as u64;
                return Err(format_err(
                    path,
                    format!(
                        "pixel ({}, {}) claims more covered samples than its range of {span}",
                        p % h.width as u64,
                        p / h.width as u64
                    ),
                ));
            }
            cover_left -= k;
        }
        let mut rest = [0u8; 1];
        if z.read(&mut rest).map_err(short)? != 0 {
            return Err(format_err(path, "there is data after the pixels"));
        }
        let consistent = if uniform_counts(h) {
            missing == h.discarded
        } else {
            missing >= h.discarded
        };
        if !consistent {
            return Err(format_err(
                path,
                format!(
                    "its pixels lack {missing} of their {} samples but its header says {} were \
                     discarded: the pixel data does not belong to this header",
                    n as u64 * span as u64,
                    h.discarded
                ),
            ));
        }

        // Second pass: the arrays, at their exact size.
        let mut z = self.pixel_stream()?;
        let mut sum: Vec<[i128; 3]> = Vec::with_capacity(n);
        let mut left = n;
        while left > 0 {
            let k = left.min(buf.len() / 48);
            z.read_exact(&mut buf[..48 * k]).map_err(short)?;
            for px in buf[..48 * k].chunks_exact(48) {
                let c = |j: usize| {
                    let mut w = [0u8; 16];
                    w.copy_from_slice(&px[16 * j..16 * j + 16]);
                    i128::from_le_bytes(w)
                };
                sum.push([c(0), c(1), c(2)]);
            }
            left -= k;
        }
        let mut count: Vec<u32> = Vec::with_capacity(n);
        let mut left = n;
        while left > 0 {
            let k = left.min(buf.len() / 4);
            z.read_exact(&mut buf[..4 * k]).map_err(short)?;
            count.extend(
                buf[..4 * k]
                    .chunks_exact(4)
                    .map(|w| u32::from_le_bytes([w[0], w[1], w[2], w[3]])),
            );
            left -= k;
        }
        let mut coverage: Vec<u32> = Vec::with_capacity(if h.coverage { n } else { 0 });
        let mut left = if h.coverage { n } else { 0 };
        while left > 0 {
            let k = left.min(buf.len() / 4);
            z.read_exact(&mut buf[..4 * k]).map_err(short)?;
            coverage.extend(
                buf[..4 * k]
                    .chunks_exact(4)
                    .map(|w| u32::from_le_bytes([w[0], w[1], w[2], w[3]])),
            );
            left -= k;
        }
        // The file may have changed between the passes: the counts are checked again with the
        // sums. Every sum is within what its count of samples below the sample limit can reach,
        // so merging parts of one frame cannot overflow.
        let limit = (SAMPLE_LIMIT as f64 * (1u64 << FRAC_BITS) as f64) as i128;
        for (i, (s, &c)) in sum.iter().zip(&count).enumerate() {
            if c > span
                || s.iter()
                    .any(|v| v.unsigned_abs() > (limit * c as i128) as u128)
            {
                return Err(format_err(
                    path,
                    format!(
                        "pixel ({}, {}) holds impossible values",
                        i as u64 % h.width as u64,
                        i as u64 / h.width as u64
                    ),
                ));
            }
        }
        drop(z);
        let mut film = Film::from_raw(h.width, h.height, sum, count, h.discarded)
            .ok_or_else(|| format_err(path, "inconsistent pixel data"))?;
        if h.coverage {
            film = film.with_coverage(coverage).ok_or_else(|| {
                format_err(
                    path,
                    "a pixel claims more covered samples (alpha) than it holds",
                )
            })?;
        }
        Ok(Part {
            header: self.header.clone(),
            film,
        })
    }
}

/// Checks that parts (by their headers) can be merged: the same frame (scene, every setting,
/// size, version, render identity), no overlap, no gap; `complete` also requires them to cover
/// every sample of the frame. Returns the sample range the merged part holds. Needs no pixels, so
/// `trayecto merge` refuses a wrong set of parts before reading any.
pub fn check_merge(parts: &[(&Path, &PartHeader)], complete: bool) -> Result<[u32; 2], PartError> {
    let err = |m: String| Err(PartError::Merge(m));
    let Some((first_path, first)) = parts.first() else {
        return err("no parts to merge".into());
    };
    for (p, h) in &parts[1..] {
        if let Some(why) = first.mismatch(h) {
            return err(format!(
                "{} does not belong to the same frame as {}: {why}",
                p.display(),
                first_path.display()
            ));
        }
    }
    let mut order: Vec<&(&Path, &PartHeader)> = parts.iter().collect();
    order.sort_by_key(|(_, h)| (h.samples[0], h.samples[1]));
    let spp = first.spp;
    let start = order[0].1.samples[0];
    if complete && start != 0 {
        return err(format!(
            "samples 0..{start} are missing (the first part, {}, starts at sample {start})",
            order[0].0.display()
        ));
    }
    for w in order.windows(2) {
        let ((pa, a), (pb, b)) = (w[0], w[1]);
        let (ae, bs) = (a.samples[1], b.samples[0]);
        if bs < ae {
            return err(format!(
                "{} (samples {}..{ae}) and {} (samples {bs}..{}) overlap on samples {bs}..{}",
                pa.display(),
                a.samples[0],
                pb.display(),
                b.samples[1],
                ae.min(b.samples[1])
            ));
        }
        if bs > ae {
            return err(format!(
                "samples {ae}..{bs} are missing (between {} and {})",
                pa.display(),
                pb.display()
            ));
        }
    }
    let (last_path, last) = order[order.len() - 1];
    let end = last.samples[1];
    if complete && end != spp {
        return err(format!(
            "samples {end}..{spp} are missing (the last part, {}, ends at sample {end})",
            last_path.display()
        ));
    }
    Ok([start, end])
}

/// Merges parts of one frame in sample order, after [`check_merge`]. The result is exact: the
/// same film whichever way the frame was split. The discarded-sample count saturates (parts of
/// one frame cannot reach it; forged ones must not wrap it round to zero).
pub fn merge(parts: Vec<(PathBuf, Part)>, complete: bool) -> Result<Part, PartError> {
    let headers: Vec<(&Path, &PartHeader)> = parts
        .iter()
        .map(|(p, part)| (p.as_path(), &part.header))
        .collect();
    let [start, end] = check_merge(&headers, complete)?;
    let first = &parts[0].1;
    let mut film = Film::new(first.header.width, first.header.height);
    if first.header.coverage {
        film = film.track_coverage();
    }
    for (p, part) in &parts {
        film.add_film(&part.film)
            .map_err(|e| PartError::Merge(format!("{}: {e}", p.display())))?;
    }
    let mut header = first.header.clone();
    header.samples = [start, end];
    header.discarded = film.discarded;
    Ok(Part { header, film })
}
