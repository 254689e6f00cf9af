//! `EXT_meshopt_compression` and `KHR_meshopt_compression`: buffer views whose bytes are stored
//! compressed by meshoptimizer's vertex and index codecs (and optionally passed through one of its
//! filters). Each such view is decoded once, after the buffers are read, with the reference
//! decoder (the `meshopt` crate); [`Loader::view_bytes`] then serves the decoded bytes.
//!
//! The decoder is documented as safe on untrusted input (a malformed stream is an error code),
//! but its C `assert`s on the *parameters* are live in debug builds, so every parameter the
//! extension text constrains is checked here first: mode, stride (ATTRIBUTES: a multiple of 4 up
//! to 256; TRIANGLES/INDICES: 2 or 4), the triangle count being a multiple of 3, and each
//! filter's stride. Memory is bounded: the decoded size may not exceed [`MAX_RATIO`] times the
//! compressed size (the codecs cannot do better, see below) nor [`MAX_DECODED_TOTAL`] in all.

use rayon::prelude::*;

use super::*;

/// The extension names and what each allows beyond the other. KHR_meshopt_compression is the
/// ratified successor: the same JSON, plus vertex codec version 1 and the COLOR filter.
const EXT: &str = "EXT_meshopt_compression";
const KHR: &str = "KHR_meshopt_compression";

/// The vertex codec spends at least 2 bits per 16 bytes of a byte column (a 64:1 ratio for
/// constant data), the index codecs at least half a byte per triangle or index, so no valid stream
/// decodes to more than 64× its size. 128× leaves a margin; anything beyond is a forged count.
const MAX_RATIO: usize = 128;

/// All decoded views of one file together: far above real models, low enough that a forged file
/// cannot exhaust memory.
const MAX_DECODED_TOTAL: usize = 1 << 31;

/// One compressed buffer view, as the extension object describes it.
#[derive(Debug)]
#[cfg_attr(not(feature = "meshopt"), allow(dead_code))]
struct Compressed<'a> {
    view: usize,
    ext: &'static str,
    source: &'a [u8],
    count: usize,
    stride: usize,
    mode: Mode,
    filter: Filter,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Mode {
    Attributes,
    Triangles,
    Indices,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Filter {
    None,
    Octahedral,
    Quaternion,
    Exponential,
    Color,
}

/// Whether buffer `b` is a meshopt fallback buffer: its bytes (if any) are only for loaders that
/// cannot decode the compressed views, so they are not read.
pub(super) fn is_fallback_buffer(b: &gltf::Buffer) -> bool {
    [EXT, KHR].iter().any(|e| {
        b.extension_value(e)
            .and_then(|v| v.get("fallback"))
            .and_then(|f| f.as_bool())
            .unwrap_or(false)
    })
}

impl Loader<'_> {
    /// Decodes every compressed buffer view (in parallel: views are independent, and each result
    /// depends only on its own bytes, so the outcome is the same for any thread count).
    pub(super) fn decode_meshopt_views(&mut self) -> Result<(), SceneError> {
        let mut jobs = Vec::new();
        for view in self.doc.views() {
            for ext in [EXT, KHR] {
                if let Some(v) = view.extension_value(ext) {
                    jobs.push(self.compressed_view(view.index(), ext, v)?);
                    break;
                }
            }
        }
        if jobs.is_empty() {
            return Ok(());
        }
        let mut total = 0usize;
        for j in &jobs {
            total = total.saturating_add(j.count.saturating_mul(j.stride));
        }
        if total > MAX_DECODED_TOTAL {
            return Err(self.err(format!(
                "{}: the compressed buffer views would decode to {total} bytes, more than the {} this loader accepts",
                jobs[0].ext, MAX_DECODED_TOTAL
            )));
        }
        let decoded: Vec<(usize, Result<Vec<u8>, String>)> = jobs
            .par_iter()
            .map(|j| {
                (
                    j.view,
                    decode(j).map_err(|e| format!("buffer view {} ({}): {e}", j.view, j.ext)),
                )
            })
            .collect();
        for (view, d) in decoded {
            let bytes = d.map_err(|e| self.err(e))?;
            self.decoded_views.insert(view, bytes);
        }
        Ok(())
    }

    /// Reads and checks one view's extension object.
    fn compressed_view<'b>(
        &'b self,
        view: usize,
        ext: &'static str,
        v: &gltf::json::Value,
    ) -> Result<Compressed<'b>, SceneError> {
        let bad = |m: String| self.err(format!("buffer view {view} ({ext}): {m}"));
        let uint = |key: &str, required: bool| -> Result<usize, SceneError> {
            match v.get(key) {
                None if !required => Ok(0),
                None => Err(bad(format!("'{key}' is missing"))),
                Some(x) => x
                    .as_u64()
                    .and_then(|x| usize::try_from(x).ok())
                    .ok_or_else(|| bad(format!("'{key}' must be a non-negative integer"))),
            }
        };
        let buffer = uint("buffer", true)?;
        let offset = uint("byteOffset", false)?;
        let length = uint("byteLength", true)?;
        let stride = uint("byteStride", true)?;
        let count = uint("count", true)?;
        if count > MAX_ACCESSOR_COUNT {
            return Err(bad(format!("an absurd element count ({count})")));
        }
        let mode = match v.get("mode").and_then(|m| m.as_str()) {
            Some("ATTRIBUTES") => Mode::Attributes,
            Some("TRIANGLES") => Mode::Triangles,
            Some("INDICES") => Mode::Indices,
            other => {
                return Err(bad(format!(
                    "mode {other:?} is not ATTRIBUTES, TRIANGLES or INDICES"
                )));
            }
        };
        let filter = match v.get("filter").map(|f| f.as_str()) {
            None | Some(Some("NONE")) => Filter::None,
            Some(Some("OCTAHEDRAL")) => Filter::Octahedral,
            Some(Some("QUATERNION")) => Filter::Quaternion,
            Some(Some("EXPONENTIAL")) => Filter::Exponential,
            Some(Some("COLOR")) if ext == KHR => Filter::Color,
            Some(other) => return Err(bad(format!("unknown filter {other:?}"))),
        };
        let data = self
            .buffers
            .get(buffer)
            .ok_or_else(|| bad(format!("buffer {buffer} does not exist")))?;
        let source = offset
            .checked_add(length)
            .and_then(|end| data.get(offset..end))
            .ok_or_else(|| {
                bad(format!(
                    "bytes {offset}..+{length} lie outside buffer {buffer} ({} bytes)",
                    data.len()
                ))
            })?;
        let stride_ok = match mode {
            Mode::Attributes => stride > 0 && stride <= 256 && stride.is_multiple_of(4),
            Mode::Triangles | Mode::Indices => stride == 2 || stride == 4,
        };
        if !stride_ok {
            return Err(bad(format!(
                "byteStride {stride} is not valid for {mode:?}"
            )));
        }
        if mode == Mode::Triangles && !count.is_multiple_of(3) {
            return Err(bad(format!(
                "TRIANGLES count {count} is not a multiple of 3"
            )));
        }
        let filter_ok = match (mode, filter) {
            (_, Filter::None) => true,
            (Mode::Attributes, Filter::Octahedral | Filter::Color) => stride == 4 || stride == 8,
            (Mode::Attributes, Filter::Quaternion) => stride == 8,
            (Mode::Attributes, Filter::Exponential) => true,
            _ => false,
        };
        if !filter_ok {
            return Err(bad(format!(
                "filter {filter:?} does not apply to {mode:?} with byteStride {stride}"
            )));
        }
        let size = count * stride;
        if size > length.saturating_mul(MAX_RATIO).saturating_add(4096) {
            return Err(bad(format!(
                "{count} elements of {stride} bytes cannot come from {length} compressed bytes (forged count?)"
            )));
        }
        Ok(Compressed {
            view,
            ext,
            source,
            count,
            stride,
            mode,
            filter,
        })
    }

    /// The bytes a buffer view holds: decoded, if it was compressed.
    pub(super) fn decoded_view(&self, view: usize) -> Option<&[u8]> {
        self.decoded_views.get(&view).map(Vec::as_slice)
    }
}

/// A build without the `meshopt` cargo feature (on by default) has no decoder: the reference
/// decoder is C++, and this lets Trayecto build with the Rust toolchain alone. Such a build still
/// reads and checks the extension objects, then refuses the file naming the extension.
#[cfg(not(feature = "meshopt"))]
fn decode(_: &Compressed) -> Result<Vec<u8>, String> {
    Err(
        "this build of Trayecto has no meshopt decoder (it was built without the cargo feature \
         'meshopt', which is on by default and needs a C++ compiler); rebuild with it, or write \
         the file without meshopt compression"
            .into(),
    )
}

/// One vertex of `N` bytes (`[u8; N]` has no `Default` beyond 32).
#[cfg(feature = "meshopt")]
#[derive(Clone, Copy)]
struct Vertex<const N: usize>([u8; N]);

#[cfg(feature = "meshopt")]
impl<const N: usize> Default for Vertex<N> {
    fn default() -> Self {
        Vertex([0; N])
    }
}

#[cfg(feature = "meshopt")]
fn decode_vertices<const N: usize>(src: &[u8], count: usize) -> Result<Vec<u8>, String> {
    let v: Vec<Vertex<N>> = ::meshopt::decode_vertex_buffer(src, count)
        .map_err(|e| format!("corrupt vertex stream ({e})"))?;
    Ok(v.iter().flat_map(|v| v.0).collect())
}

/// Dispatches the vertex decoder on the stride (a multiple of 4 up to 256, checked above).
#[cfg(feature = "meshopt")]
fn decode_vertex_stride(src: &[u8], count: usize, stride: usize) -> Result<Vec<u8>, String> {
    macro_rules! strides {
        ($($n:literal)*) => {
            match stride {
                $($n => decode_vertices::<$n>(src, count),)*
                _ => Err(format!("byteStride {stride} is not a multiple of 4 up to 256")),
            }
        };
    }
    strides!(4 8 12 16 20 24 28 32 36 40 44 48 52 56 60 64 68 72 76 80 84 88 92 96 100 104 108
        112 116 120 124 128 132 136 140 144 148 152 156 160 164 168 172 176 180 184 188 192 196
        200 204 208 212 216 220 224 228 232 236 240 244 248 252 256)
}

#[cfg(feature = "meshopt")]
fn decode(c: &Compressed) -> Result<Vec<u8>, String> {
    if c.count == 0 {
        return Ok(Vec::new());
    }
    let corrupt = |what: &str, e: ::meshopt::Error| format!("corrupt {what} stream ({e})");
    let mut out = match (c.mode, c.stride) {
        (Mode::Attributes, s) => decode_vertex_stride(c.source, c.count, s)?,
        (Mode::Triangles, 2) => ::meshopt::decode_index_buffer::<u16>(c.source, c.count)
            .map_err(|e| corrupt("index", e))?
            .iter()
            .flat_map(|i| i.to_le_bytes())
            .collect(),
        (Mode::Triangles, _) => ::meshopt::decode_index_buffer::<u32>(c.source, c.count)
            .map_err(|e| corrupt("index", e))?
            .iter()
            .flat_map(|i| i.to_le_bytes())
            .collect(),
        (Mode::Indices, 2) => ::meshopt::decode_index_sequence::<u16>(c.source, c.count)
            .map_err(|e| corrupt("index sequence", e))?
            .iter()
            .flat_map(|i| i.to_le_bytes())
            .collect(),
        (Mode::Indices, _) => ::meshopt::decode_index_sequence::<u32>(c.source, c.count)
            .map_err(|e| corrupt("index sequence", e))?
            .iter()
            .flat_map(|i| i.to_le_bytes())
            .collect(),
    };
    apply_filter(&mut out, c.filter, c.stride);
    Ok(out)
}

/// Undoes a vertex filter in place (extension text, "Filters"). Strides were checked against the
/// filter when the view was read.
#[cfg(feature = "meshopt")]
fn apply_filter(data: &mut [u8], filter: Filter, stride: usize) {
    fn through<T: Copy + Default, const K: usize>(
        data: &mut [u8],
        size: usize,
        from: fn([u8; 8]) -> [T; K],
        to: fn([T; K]) -> Vec<u8>,
        f: impl Fn(&mut [[T; K]]),
    ) {
        let mut v: Vec<[T; K]> = data
            .chunks_exact(size)
            .map(|c| {
                let mut b = [0u8; 8];
                b[..size].copy_from_slice(c);
                from(b)
            })
            .collect();
        f(&mut v);
        for (dst, e) in data.chunks_exact_mut(size).zip(v) {
            dst.copy_from_slice(&to(e));
        }
    }
    let i8x4 = |b: [u8; 8]| [b[0] as i8, b[1] as i8, b[2] as i8, b[3] as i8];
    let u8x4 = |b: [u8; 8]| [b[0], b[1], b[2], b[3]];
    let i16x4 = |b: [u8; 8]| [0, 2, 4, 6].map(|k| i16::from_le_bytes([b[k], b[k + 1]]));
    let u16x4 = |b: [u8; 8]| [0, 2, 4, 6].map(|k| u16::from_le_bytes([b[k], b[k + 1]]));
    let u32x1 = |b: [u8; 8]| [u32::from_le_bytes([b[0], b[1], b[2], b[3]])];
    match (filter, stride) {
        (Filter::None, _) => {}
        (Filter::Octahedral, 4) => through(
            data,
            4,
            i8x4,
            |e| e.iter().map(|&x| x as u8).collect(),
            ::meshopt::decode_filter_oct::<i8>,
        ),
        (Filter::Octahedral, _) => through(
            data,
            8,
            i16x4,
            |e| e.iter().flat_map(|x| x.to_le_bytes()).collect(),
            ::meshopt::decode_filter_oct::<i16>,
        ),
        (Filter::Quaternion, _) => through(
            data,
            8,
            i16x4,
            |e| e.iter().flat_map(|x| x.to_le_bytes()).collect(),
            ::meshopt::decode_filter_quat,
        ),
        (Filter::Color, 4) => through(
            data,
            4,
            u8x4,
            |e| e.to_vec(),
            ::meshopt::decode_filter_color::<u8>,
        ),
        (Filter::Color, _) => through(
            data,
            8,
            u16x4,
            |e| e.iter().flat_map(|x| x.to_le_bytes()).collect(),
            ::meshopt::decode_filter_color::<u16>,
        ),
        // Each 32-bit component is decoded on its own (2^E·M), whatever the stride.
        (Filter::Exponential, _) => through(
            data,
            4,
            u32x1,
            |e| e[0].to_le_bytes().to_vec(),
            ::meshopt::decode_filter_exp::<1>,
        ),
    }
}
