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
//! | rest | a zlib stream (RFC 1950, with its Adler-32 check) of: `width·height` pixels × 3 channels of `i128` fixed-point sums (row-major, top row first, RGB; value = sum · 2^-`frac_bits`), then `width·height` `u32` sample counts |
//!
//! The header names the scene by content (a SHA-256 of the scene file's bytes and of everything
//! the loader read from it, see [`crate::scene::digest`]), lists every setting that changes the
//! image, the image size, the frame's samples per pixel, the sample range it holds, the fixed-point
//! format, the Trayecto version and the render identity ([`crate::RENDER_IDENTITY`], a hash of the
//! sources of the build). Reading checks everything a hostile or truncated file could get
//! wrong before allocating, and that every sum is within what its count of samples can reach.

use crate::film::{FRAC_BITS, Film, SAMPLE_LIMIT};
use crate::light::default_light::DefaultLight;
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

/// The settings that change the image, as name → value strings (floats in Rust's shortest
/// round-trip form, so equal strings mean equal values). Thread count, exposure and tone mapping
/// are left out: they do not change the film. The environment map's path is left out too (machines
/// may mount it elsewhere); its content is part of the scene digest. `light_sampler` is the
/// sampler the built world uses ([`crate::light::LightSet::sampler_kind`]), never `auto`: `auto`
/// resolves to different samplers by light count and version.
pub fn image_settings(
    s: &RenderSettings,
    w: &WorldOptions,
    light_sampler: crate::light::LightSamplerKind,
) -> BTreeMap<String, String> {
    debug_assert!(
        light_sampler != crate::light::LightSamplerKind::Auto,
        "image_settings wants the resolved light sampler"
    );
    let mut m = BTreeMap::new();
    let mut put = |k: &str, v: String| {
        m.insert(k.to_string(), v);
    };
    put("seed", s.seed.to_string());
    put("sampler", format!("{:?}", s.sampler));
    put("integrator", format!("{:?}", s.integrator));
    put("max_depth", s.path.max_depth.to_string());
    put("rr_depth", s.path.rr_depth.to_string());
    put("rr_scale", format!("{:?}", s.path.rr_scale));
    put("nee", s.path.nee.to_string());
    put("mis", s.path.mis.to_string());
    put("secondary", s.path.secondary.to_string());
    // Keys added with filters and crops are written only when not the default, so partial films
    // of default renders keep the headers they had (and still merge with older parts).
    if !s.filter.is_default_box() {
        put("filter", s.filter.describe());
    }
    if let Some(c) = s.crop {
        put(
            "crop",
            format!(
                "{}x{} pixels {}..{}, {}..{}",
                s.width, s.height, c.x0, c.x1, c.y0, c.y1
            ),
        );
    }
    put("accel", format!("{:?}", w.accel));
    put("camera", format!("{:?}", w.camera));
    put(
        "default_light",
        w.default_light
            .map_or("file", DefaultLight::name)
            .to_string(),
    );
    put("env_map", w.env.is_some().to_string());
    // Only when given, so that older partial films still merge.
    if let Some(c) = &w.camera_override {
        put("camera_view", format!("{c:?}"));
    }
    if w.env_rotation != 0.0 {
        put("env_rotation", format!("{:?}", w.env_rotation));
    }
    // Always, and the resolved kind: `auto` picks power / bvh / bvh8 by the scene's light count,
    // and has picked differently in different versions.
    put("light_sampler", light_sampler.name().to_string());
    m
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
                return diff(&format!("the setting '{k}'"), &show(a), &show(b));
            }
        }
        None
    }
}

impl Part {
    /// Writes the part to `path` atomically: to a temporary file beside it, flushed to disk, then
    /// renamed over `path`, so a crash leaves either the old file or the new one, never half.
    pub fn write(&self, path: &Path) -> Result<(), PartError> {
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
            let header = serde_json::to_vec(&self.header).map_err(std::io::Error::other)?;
            out.write_all(MAGIC)?;
            out.write_all(&(header.len() as u32).to_le_bytes())?;
            out.write_all(&header)?;
            let mut z = flate2::write::ZlibEncoder::new(out, flate2::Compression::fast());
            let (sum, count) = self.film.raw();
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
            for n in count {
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

    /// Reads and checks a part.
    pub fn read(path: &Path) -> Result<Part, PartError> {
        let io = |source| PartError::Io {
            path: path.to_path_buf(),
            source,
        };
        let file = std::fs::File::open(path).map_err(io)?;
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
        // Decompress exactly the expected number of bytes (and refuse more: no zip bombs).
        let n = pixels as usize;
        let expected = n as u64 * (48 + 4);
        let mut z = flate2::read::ZlibDecoder::new(r).take(expected + 1);
        // Capacity grows with the data actually decompressed: a header that lies about the size
        // cannot make us allocate gigabytes up front.
        let mut sum = Vec::with_capacity(n.min(1 << 16));
        let mut word = [0u8; 16];
        let short = |_| format_err(path, "the pixel data is truncated or corrupt");
        for _ in 0..n {
            let mut px = [0i128; 3];
            for c in &mut px {
                z.read_exact(&mut word).map_err(short)?;
                *c = i128::from_le_bytes(word);
            }
            sum.push(px);
        }
        let mut count = Vec::with_capacity(n.min(1 << 16));
        let mut w4 = [0u8; 4];
        for _ in 0..n {
            z.read_exact(&mut w4).map_err(short)?;
            count.push(u32::from_le_bytes(w4));
        }
        let mut rest = Vec::new();
        z.read_to_end(&mut rest).map_err(short)?;
        if !rest.is_empty() {
            return Err(format_err(path, "there is data after the pixels"));
        }
        // Every count is at most the range's length, and every sum within what that many samples
        // below the sample limit can reach, so merging parts of one frame cannot overflow.
        let limit = (SAMPLE_LIMIT as f64 * (1u64 << FRAC_BITS) as f64) as i128;
        for (i, (s, &c)) in sum.iter().zip(&count).enumerate() {
            if c > b - a
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
        let film = Film::from_raw(h.width, h.height, sum, count, h.discarded)
            .ok_or_else(|| format_err(path, "inconsistent pixel data"))?;
        Ok(Part { header: h, film })
    }
}

/// Merges parts of one frame in sample order. Refuses parts that do not belong to the same frame
/// (scene, settings, size, version, render identity), that overlap, or that leave a gap; `complete` also requires
/// the parts to cover every sample of the frame (the merged part is otherwise a longer range, to
/// be merged further). The result is exact: the same film whichever way the frame was split.
pub fn merge(parts: Vec<(PathBuf, Part)>, complete: bool) -> Result<Part, PartError> {
    let err = |m: String| Err(PartError::Merge(m));
    if parts.is_empty() {
        return err("no parts to merge".into());
    }
    let (first_path, first) = &parts[0];
    for (p, part) in &parts[1..] {
        if let Some(why) = first.header.mismatch(&part.header) {
            return err(format!(
                "{} does not belong to the same frame as {}: {why}",
                p.display(),
                first_path.display()
            ));
        }
    }
    let mut order: Vec<&(PathBuf, Part)> = parts.iter().collect();
    order.sort_by_key(|(_, p)| (p.header.samples[0], p.header.samples[1]));
    let spp = first.header.spp;
    let start = order[0].1.header.samples[0];
    if complete && start != 0 {
        return err(format!(
            "samples 0..{start} are missing (the first part, {}, starts at sample {start})",
            order[0].0.display()
        ));
    }
    for w in order.windows(2) {
        let ((pa, a), (pb, b)) = (w[0], w[1]);
        let (ae, bs) = (a.header.samples[1], b.header.samples[0]);
        if bs < ae {
            return err(format!(
                "{} (samples {}..{ae}) and {} (samples {bs}..{}) overlap on samples {bs}..{}",
                pa.display(),
                a.header.samples[0],
                pb.display(),
                b.header.samples[1],
                ae.min(b.header.samples[1])
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
    let end = last.header.samples[1];
    if complete && end != spp {
        return err(format!(
            "samples {end}..{spp} are missing (the last part, {}, ends at sample {end})",
            last_path.display()
        ));
    }
    let mut film = Film::new(first.header.width, first.header.height);
    for (p, part) in &order {
        film.add_film(&part.film)
            .map_err(|e| PartError::Merge(format!("{}: {e}", p.display())))?;
    }
    let mut header = first.header.clone();
    header.samples = [start, end];
    header.discarded = film.discarded;
    Ok(Part { header, film })
}
