//! Arbitrary output variables (AOVs): per-pixel layers written beside the beauty image
//! (docs/DESIGN.md §5). The geometric ones (albedo, normals, depth, position, ids) are traced by
//! [`crate::integrator::aov`]; layers that come from the film itself (sample counts, variance)
//! are built from it. All of them are [`Layer`]s, which [`crate::pipeline::write_outputs`]
//! writes into one multi-layer EXR, or as side files `out.NAME.png` beside other formats.
//!
//! Channel names follow the OpenEXR layer convention that OpenImageIO, Nuke and Blender read
//! (OpenEXR "Interpreting OpenEXR deep pixels"/"multi-view" notes; OIIO's `ImageSpec` channel
//! names): `LAYER.CHANNEL`, the layer a dotted prefix, colour channels `R G B`, vectors `X Y Z`.
//! Depth is the bare standard channel `Z` (OpenEXR's depth channel, which Nuke shows as
//! `depth.Z`). The ids use Blender's pass names `IndexMA.X` and `IndexOB.X`.

use crate::math::Vec3;
use std::path::{Path, PathBuf};

/// One AOV that can be asked for with `--aov`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum AovKind {
    /// Reflectance at the first non-specular hit, following perfect-specular chains (their
    /// weights multiplied in): what denoisers (OIDN) want as the albedo guide.
    Albedo,
    /// Shading normal (world space, facing the viewer) at the same hit as `Albedo`: OIDN's normal
    /// guide.
    Normal,
    /// Distance along the camera ray to the first visible surface, in scene units.
    Depth,
    /// World-space position of the first visible surface.
    Position,
    /// Shading normal (world space, normal-mapped, facing the viewer) of the first visible
    /// surface, mirrors and glass included.
    ShadingNormal,
    /// Index (+1) of the material of the first visible surface; 0 where nothing is hit.
    MaterialId,
    /// Index (+1) of the object (mesh or analytic shape) first visible; 0 where nothing is hit.
    ObjectId,
    /// Samples the pixel's estimate holds: the frame's spp on a uniform render, less any
    /// discarded (NaN, infinite) samples; fewer where adaptive sampling stopped. From the film,
    /// not traced ([`AovKind::is_traced`]).
    Samples,
    /// The unbiased sample variance s² of the luminance of the pixel's samples: the variance of
    /// one sample, what adaptive sampling judges a pixel by (the variance of the pixel's mean is
    /// s²/n). From the film's exact squared-luminance sums, not traced ([`AovKind::is_traced`]).
    Variance,
    /// Coverage: the fraction of the pixel's camera rays that hit geometry (OpenEXR's `A`).
    /// With `--transparent` the background seen by camera rays is not rendered, so the beauty
    /// image is premultiplied by it. Not in `--aov all` (a PNG takes it as its alpha channel).
    /// From the film's exact coverage counts ([`crate::film::Film::track_coverage`]), not traced,
    /// so it is kept in partial films and checkpoints and merges exactly.
    Alpha,
    /// One strategy of the bidirectional path tracer alone (pbrt-v4's `visualizestrategies` and
    /// `visualizeweights`): rendered by `render::light::render_strategies` in a pass of its own
    /// over the beauty image's samples, neither traced per hit nor read from the film.
    Strategy(Strategy),
}

/// Strategy (s, t) of bidirectional path tracing (Veach 1997 §10.2): the paths made by joining
/// the first s vertices of a light subpath to the first t of a camera subpath, a path of depth
/// s + t − 2 (bounces). `weighted`: its contribution to the image, times its multiple importance
/// sampling weight (the weighted layers of every strategy up to the render's depth add up to the
/// beauty image); otherwise the strategy alone, an estimate of the image of the paths of its
/// depth that it can sample. Named `bdpt-sS-tT` and `bdpt-sS-tT-unweighted`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct Strategy {
    pub s: u8,
    pub t: u8,
    pub weighted: bool,
}

impl Strategy {
    /// The deepest strategy that can be asked for (depth s + t − 2): the layers are for looking
    /// at, and deeper paths are a sliver of most images.
    pub const MAX_DEPTH: u32 = 8;

    /// (s, t) if it is a strategy BDPT has: t ≥ 1 (every path reaches the lens), and (1, 1) is
    /// left out (the light seen directly is (0, 2)), at most [`Strategy::MAX_DEPTH`] deep.
    pub fn new(s: u32, t: u32, weighted: bool) -> Option<Strategy> {
        let valid = t >= 1 && s + t >= 2 && !(s == 1 && t == 1);
        (valid && s + t - 2 <= Strategy::MAX_DEPTH).then_some(Strategy {
            s: s as u8,
            t: t as u8,
            weighted,
        })
    }

    /// The depth (bounces) of the paths the strategy makes: s + t − 2.
    pub fn depth(self) -> u32 {
        u32::from(self.s) + u32::from(self.t) - 2
    }

    /// Every strategy of depth `depth`, from s = 0 (the camera subpath hits a light) to s =
    /// depth + 1 (a light subpath joined to the lens).
    pub fn of_depth(depth: u32, weighted: bool) -> Vec<Strategy> {
        (0..=depth + 1)
            .filter_map(|s| Strategy::new(s, depth + 2 - s, weighted))
            .collect()
    }

    /// Parses `bdpt-sS-tT` or `bdpt-sS-tT-unweighted`.
    fn parse(name: &str) -> Option<Strategy> {
        let rest = name.strip_prefix("bdpt-s")?;
        let (rest, weighted) = match rest.strip_suffix("-unweighted") {
            Some(r) => (r, false),
            None => (rest, true),
        };
        let (s, t) = rest.split_once("-t")?;
        let digits =
            |x: &str| !x.is_empty() && x.len() <= 2 && x.bytes().all(|b| b.is_ascii_digit());
        if !digits(s) || !digits(t) {
            return None;
        }
        Strategy::new(s.parse().ok()?, t.parse().ok()?, weighted)
    }

    /// Parses a group `bdpt-depthD` (or `bdpt-depthD-unweighted`): every strategy of depth D.
    fn parse_group(name: &str) -> Option<Vec<Strategy>> {
        let rest = name.strip_prefix("bdpt-depth")?;
        let (d, weighted) = match rest.strip_suffix("-unweighted") {
            Some(r) => (r, false),
            None => (rest, true),
        };
        let d: u32 = d.parse().ok().filter(|&d| d <= Strategy::MAX_DEPTH)?;
        Some(Strategy::of_depth(d, weighted))
    }

    /// Its names and channels, from a table made once (the names are `&'static` like every
    /// other AOV's): (name, [R, G, B] channel names).
    fn names(self) -> (&'static str, &'static [&'static str]) {
        type Names = (&'static str, &'static [&'static str]);
        static TABLE: std::sync::OnceLock<Vec<Names>> = std::sync::OnceLock::new();
        let n = Strategy::MAX_DEPTH as usize + 3;
        let index = |s: usize, t: usize, w: bool| (s * n + t) * 2 + usize::from(w);
        let table = TABLE.get_or_init(|| {
            let mut table: Vec<Names> = vec![("", &[]); n * n * 2];
            for s in 0..n {
                for t in 0..n {
                    for w in [false, true] {
                        let suffix = if w { "" } else { "-unweighted" };
                        // Leaked once: a fixed table of a few hundred short strings.
                        let name: &'static str = format!("bdpt-s{s}-t{t}{suffix}").leak();
                        let channels: Vec<&'static str> = ["R", "G", "B"]
                            .iter()
                            .map(|c| &*format!("{name}.{c}").leak())
                            .collect();
                        table[index(s, t, w)] = (name, channels.leak());
                    }
                }
            }
            table
        });
        table[index(self.s as usize, self.t as usize, self.weighted)]
    }
}

impl AovKind {
    /// Every AOV `--aov all` asks for.
    pub const ALL: [AovKind; 9] = [
        AovKind::Albedo,
        AovKind::Normal,
        AovKind::Depth,
        AovKind::Position,
        AovKind::ShadingNormal,
        AovKind::MaterialId,
        AovKind::ObjectId,
        AovKind::Samples,
        AovKind::Variance,
    ];

    /// The AOVs traced per hit by [`crate::integrator::aov`] (in the path loop or a pass of
    /// their own).
    pub const TRACED: [AovKind; 7] = [
        AovKind::Albedo,
        AovKind::Normal,
        AovKind::Depth,
        AovKind::Position,
        AovKind::ShadingNormal,
        AovKind::MaterialId,
        AovKind::ObjectId,
    ];

    /// The per-pixel statistics of the film itself ([`film_layers`]): any render of a whole
    /// frame has them, whatever its integrator.
    pub const FILM: [AovKind; 2] = [AovKind::Samples, AovKind::Variance];

    /// Whether the AOV is traced per hit ([`AovKind::TRACED`]) rather than read from the film
    /// ([`AovKind::FILM`]). The tracing code skips film AOVs; [`film_layers`] skips traced ones.
    pub fn is_traced(self) -> bool {
        !matches!(
            self,
            AovKind::Samples | AovKind::Variance | AovKind::Alpha | AovKind::Strategy(_)
        )
    }

    /// Whether the AOV is one of the bidirectional path tracer's strategies ([`Strategy`]).
    pub fn is_strategy(self) -> bool {
        matches!(self, AovKind::Strategy(_))
    }

    /// The name given to `--aov` and used for side files (`out.NAME.png`).
    pub fn name(self) -> &'static str {
        match self {
            AovKind::Albedo => "albedo",
            AovKind::Normal => "normal",
            AovKind::Depth => "depth",
            AovKind::Position => "position",
            AovKind::ShadingNormal => "shading_normal",
            AovKind::MaterialId => "material_id",
            AovKind::ObjectId => "object_id",
            AovKind::Samples => "samples",
            AovKind::Variance => "variance",
            AovKind::Alpha => "alpha",
            AovKind::Strategy(st) => st.names().0,
        }
    }

    /// The EXR channel names, in pixel order.
    pub fn channels(self) -> &'static [&'static str] {
        match self {
            AovKind::Albedo => &["albedo.R", "albedo.G", "albedo.B"],
            AovKind::Normal => &["normal.X", "normal.Y", "normal.Z"],
            AovKind::Depth => &["Z"],
            AovKind::Position => &["P.X", "P.Y", "P.Z"],
            AovKind::ShadingNormal => &["N.X", "N.Y", "N.Z"],
            AovKind::MaterialId => &["IndexMA.X"],
            AovKind::ObjectId => &["IndexOB.X"],
            // The names adaptive renders have always written.
            AovKind::Samples => &["samples.Y"],
            AovKind::Variance => &["variance.Y"],
            // The beauty image's own alpha channel: the bare standard name, like `Z`.
            AovKind::Alpha => &["A"],
            AovKind::Strategy(st) => st.names().1,
        }
    }

    pub fn from_name(s: &str) -> Option<AovKind> {
        Some(match s {
            "albedo" => AovKind::Albedo,
            "normal" | "normals" => AovKind::Normal,
            "depth" | "z" | "Z" => AovKind::Depth,
            "position" | "P" => AovKind::Position,
            "shading_normal" | "N" => AovKind::ShadingNormal,
            "material_id" => AovKind::MaterialId,
            "object_id" => AovKind::ObjectId,
            "samples" => AovKind::Samples,
            "variance" => AovKind::Variance,
            "alpha" | "A" => AovKind::Alpha,
            _ => return Strategy::parse(s).map(AovKind::Strategy),
        })
    }

    /// Parses `--aov a,b,c` (`all` for every AOV; `bdpt-depthD` for every strategy of depth
    /// D); duplicates are dropped, order is kept.
    pub fn parse_list(s: &str) -> Result<Vec<AovKind>, String> {
        let mut out = Vec::new();
        for item in s.split(',').map(str::trim).filter(|i| !i.is_empty()) {
            let kinds: Vec<AovKind> = if item == "all" {
                AovKind::ALL.to_vec()
            } else if let Some(group) = Strategy::parse_group(item) {
                group.into_iter().map(AovKind::Strategy).collect()
            } else {
                vec![AovKind::from_name(item).ok_or_else(|| {
                    format!(
                        "unknown AOV '{item}' (expected a comma-separated list of {}, or all; \
                         with --integrator bdpt also bdpt-sS-tT for strategy (s, t) weighted, \
                         bdpt-sS-tT-unweighted alone, bdpt-depthD[-unweighted] for every \
                         strategy of depth D ≤ {})",
                        AovKind::ALL.map(|k| k.name()).join(", "),
                        Strategy::MAX_DEPTH
                    )
                })?]
            };
            for k in kinds {
                if !out.contains(&k) {
                    out.push(k);
                }
            }
        }
        if out.is_empty() {
            return Err("--aov needs at least one AOV name".into());
        }
        Ok(out)
    }
}

/// How a layer is shown in a display-referred side file (PNG/PPM).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Display {
    /// Colour in [0, 1] (albedo): sRGB-encoded like the beauty image.
    Colour,
    /// A unit vector mapped to (v + 1) / 2, no transfer curve (normal maps' convention).
    UnitVector,
    /// A scalar or vector normalised by the layer's finite range to [0, 1] (depth, position,
    /// sample counts).
    Range,
    /// Integer ids shown as distinct colours (a hash); 0 (nothing) is black.
    Id,
    /// A value in [0, 1] written as it is (coverage): 0 black, 1 white.
    Linear,
}

/// One per-pixel layer: `channels.len()` values per pixel, interleaved, rows top first.
#[derive(Clone, Debug, PartialEq)]
pub struct Layer {
    /// The side-file name (`out.NAME.png`) and `--aov` name.
    pub name: String,
    /// Full EXR channel names (`albedo.R`, `Z`, …), in pixel order.
    pub channels: Vec<String>,
    pub display: Display,
    pub width: u32,
    pub height: u32,
    pub data: Vec<f32>,
}

impl Layer {
    pub fn new(kind: AovKind, width: u32, height: u32, data: Vec<f32>) -> Layer {
        let display = match kind {
            AovKind::Albedo => Display::Colour,
            AovKind::Normal | AovKind::ShadingNormal => Display::UnitVector,
            AovKind::Depth | AovKind::Position => Display::Range,
            AovKind::MaterialId | AovKind::ObjectId => Display::Id,
            AovKind::Samples | AovKind::Variance => Display::Range,
            // Coverage is already in [0, 1]: shown linearly as grey.
            AovKind::Alpha => Display::Linear,
            AovKind::Strategy(_) => Display::Colour,
        };
        debug_assert_eq!(
            data.len(),
            width as usize * height as usize * kind.channels().len()
        );
        Layer {
            name: kind.name().into(),
            channels: kind.channels().iter().map(|c| c.to_string()).collect(),
            display,
            width,
            height,
            data,
        }
    }

    /// A layer that is not one of the traced [`AovKind`]s (e.g. one computed from the film, such
    /// as per-pixel sample counts): `channels` are full EXR names, `data` interleaved.
    pub fn from_channels(
        name: &str,
        channels: &[&str],
        display: Display,
        width: u32,
        height: u32,
        data: Vec<f32>,
    ) -> Layer {
        assert_eq!(
            data.len(),
            width as usize * height as usize * channels.len(),
            "layer {name}: data does not match its size"
        );
        Layer {
            name: name.into(),
            channels: channels.iter().map(|c| c.to_string()).collect(),
            display,
            width,
            height,
            data,
        }
    }

    pub fn depth(&self) -> usize {
        self.channels.len()
    }

    /// The value of channel `c` at pixel (x, y).
    pub fn get(&self, x: u32, y: u32, c: usize) -> f32 {
        self.data[(y as usize * self.width as usize + x as usize) * self.depth() + c]
    }

    /// A 3-channel layer as an RGB image (for the denoiser's guides and tests).
    pub fn to_image(&self) -> Option<super::Image> {
        (self.depth() == 3).then(|| super::Image {
            width: self.width,
            height: self.height,
            data: self
                .data
                .chunks_exact(3)
                .map(|c| Vec3::new(c[0], c[1], c[2]))
                .collect(),
        })
    }

    /// The layer as a display-referred RGB image in [0, 1] for a PNG/PPM side file (see
    /// [`Display`]); the linear values are in the EXR.
    pub fn display_image(&self) -> super::Image {
        let d = self.depth();
        let px = |i: usize| -> Vec3 {
            let v = &self.data[i * d..i * d + d];
            match d {
                1 => Vec3::splat(v[0]),
                2 => Vec3::new(v[0], v[1], 0.0),
                _ => Vec3::new(v[0], v[1], v[2]),
            }
        };
        let n = self.width as usize * self.height as usize;
        let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
        if self.display == Display::Range {
            for &v in self.data.iter().filter(|v| v.is_finite()) {
                lo = lo.min(v);
                hi = hi.max(v);
            }
        }
        let span = if hi > lo { hi - lo } else { 1.0 };
        let data = (0..n)
            .map(|i| {
                let p = px(i);
                match self.display {
                    // The writer's sRGB curve is applied with the `clamp` tone map.
                    Display::Colour => p,
                    // Written with the sRGB curve too: undo it so the file holds (v + 1) / 2.
                    Display::UnitVector => srgb_to_linear((p + Vec3::ONE) * 0.5),
                    Display::Range => {
                        let f = |v: f32| if v.is_finite() { (v - lo) / span } else { 1.0 };
                        srgb_to_linear(Vec3::new(f(p.x), f(p.y), f(p.z)))
                    }
                    Display::Id => srgb_to_linear(id_colour(p.x)),
                    Display::Linear => srgb_to_linear(p.clamp(Vec3::ZERO, Vec3::ONE)),
                }
            })
            .collect();
        super::Image {
            width: self.width,
            height: self.height,
            data,
        }
    }
}

/// The layers of the film AOVs among `kinds` ([`AovKind::FILM`], in `kinds` order; traced kinds
/// are skipped): `samples`, the samples each pixel holds, and `variance`, the unbiased variance
/// s² of its samples' luminance ([`super::Film::variance`]; 0 for a pixel with fewer than two
/// samples). The variance needs a film that tracked squared luminance
/// ([`crate::render::RenderSettings::tracks_variance`]); the caller checks that.
pub fn film_layers(film: &super::Film, kinds: &[AovKind]) -> Vec<Layer> {
    let n = film.counts().len();
    kinds
        .iter()
        .filter_map(|&k| {
            let data = match k {
                AovKind::Samples => film.counts().iter().map(|&c| c as f32).collect(),
                AovKind::Variance => (0..n).map(|i| film.variance(i) as f32).collect(),
                AovKind::Alpha => film.alpha()?,
                _ => return None,
            };
            Some(Layer::new(k, film.width, film.height, data))
        })
        .collect()
}

/// The inverse of the sRGB transfer curve the PNG writer applies (IEC 61966-2-1), so values
/// meant to be stored as-is survive it.
fn srgb_to_linear(c: Vec3) -> Vec3 {
    let f = |v: f32| {
        let v = v.clamp(0.0, 1.0);
        if v <= 0.04045 {
            v / 12.92
        } else {
            ((v + 0.055) / 1.055).powf(2.4)
        }
    };
    Vec3::new(f(c.x), f(c.y), f(c.z))
}

/// A distinct, stable colour for an id (black for 0): an integer hash's bytes.
fn id_colour(id: f32) -> Vec3 {
    if !(id >= 1.0) {
        return Vec3::ZERO;
    }
    let mut h = (id as u32).wrapping_mul(0x9E37_79B9);
    h ^= h >> 15;
    h = h.wrapping_mul(0x85EB_CA6B);
    h ^= h >> 13;
    let b = |s: u32| (((h >> s) & 0xff) as f32 / 255.0) * 0.8 + 0.2;
    Vec3::new(b(0), b(8), b(16))
}

/// The side file of `layer` beside the output `path`: `out.png` → `out.albedo.png`.
pub fn side_path(path: &Path, name: &str) -> PathBuf {
    let stem = path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    let ext = path
        .extension()
        .map(|e| e.to_string_lossy().into_owned())
        .unwrap_or_default();
    path.with_file_name(format!("{stem}.{name}.{ext}"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip_and_lists_parse() {
        for k in AovKind::ALL {
            assert_eq!(AovKind::from_name(k.name()), Some(k));
        }
        assert_eq!(
            AovKind::parse_list("albedo, normal,albedo,Z").unwrap(),
            vec![AovKind::Albedo, AovKind::Normal, AovKind::Depth]
        );
        assert_eq!(AovKind::parse_list("all").unwrap(), AovKind::ALL.to_vec());
        let e = AovKind::parse_list("albedo,wireframe").unwrap_err();
        assert!(e.contains("wireframe") && e.contains("object_id"), "{e}");
        assert!(AovKind::parse_list(" , ").is_err());
    }

    /// BDPT's strategy layers: names round-trip, a depth group lists its strategies from s = 0,
    /// and what is not a strategy BDPT has is refused (t = 0, (1, 1), too deep, junk).
    #[test]
    fn strategy_names_parse() {
        let st = |s, t, w| AovKind::Strategy(Strategy::new(s, t, w).unwrap());
        for d in 0..=Strategy::MAX_DEPTH {
            for w in [false, true] {
                for k in Strategy::of_depth(d, w) {
                    let k = AovKind::Strategy(k);
                    assert_eq!(AovKind::from_name(k.name()), Some(k));
                    assert_eq!(k.channels()[0], format!("{}.R", k.name()));
                }
            }
        }
        assert_eq!(st(2, 1, true).name(), "bdpt-s2-t1");
        assert_eq!(st(0, 3, false).name(), "bdpt-s0-t3-unweighted");
        assert_eq!(
            AovKind::parse_list("bdpt-depth1-unweighted,albedo").unwrap(),
            vec![
                st(0, 3, false),
                st(1, 2, false),
                st(2, 1, false),
                AovKind::Albedo
            ]
        );
        assert_eq!(
            AovKind::parse_list("bdpt-depth0").unwrap(),
            vec![st(0, 2, true)]
        );
        for bad in [
            "bdpt-s1-t1",
            "bdpt-s3-t0",
            "bdpt-s0-t11",
            "bdpt-s-t2",
            "bdpt-s+1-t2",
            "bdpt-s1-t2-weighted",
            "bdpt-depth9",
        ] {
            assert_eq!(AovKind::from_name(bad), None, "{bad}");
            assert!(AovKind::parse_list(bad).is_err(), "{bad}");
        }
        assert!(!st(2, 2, true).is_traced() && st(2, 2, true).is_strategy());
    }

    /// Every AOV is either traced or read from the film, and the two lists say which.
    #[test]
    fn traced_and_film_aovs_partition_all() {
        for k in AovKind::ALL {
            assert_eq!(AovKind::TRACED.contains(&k), k.is_traced(), "{k:?}");
            assert_eq!(AovKind::FILM.contains(&k), !k.is_traced(), "{k:?}");
        }
        assert_eq!(
            AovKind::TRACED.len() + AovKind::FILM.len(),
            AovKind::ALL.len()
        );
        assert_eq!(
            AovKind::parse_list("samples,variance").unwrap(),
            AovKind::FILM.to_vec()
        );
    }

    #[test]
    fn channel_names_are_unique_and_not_the_beauty_channels() {
        let mut all: Vec<&str> = AovKind::ALL
            .iter()
            .flat_map(|k| k.channels())
            .copied()
            .collect();
        let n = all.len();
        all.sort();
        all.dedup();
        assert_eq!(all.len(), n);
        for beauty in ["R", "G", "B", "A"] {
            assert!(!all.contains(&beauty));
        }
    }

    #[test]
    fn side_paths_keep_the_folder_and_format() {
        assert_eq!(
            side_path(Path::new("dir/out.png"), "albedo"),
            PathBuf::from("dir/out.albedo.png")
        );
        assert_eq!(
            side_path(Path::new("out.v2.exr"), "denoised"),
            PathBuf::from("out.v2.denoised.exr")
        );
    }
}
