//! `EXT_meshopt_compression` and `KHR_meshopt_compression`: buffer views whose bytes are stored
//! compressed by meshoptimizer's vertex and index codecs (and optionally passed through one of its
//! filters). Each such view is decoded once, after the buffers are read, with the pure-Rust
//! decoder of the `meshoptimizer-rs` crate (see [`decode`]); [`Loader::view_bytes`] then serves
//! the decoded bytes.
//!
//! The decoder checks its input (a malformed stream is an error), and every parameter the
//! extension text constrains is checked here first as well, so that the error names what is
//! wrong: mode, stride (ATTRIBUTES: a multiple of 4 up to 256; TRIANGLES/INDICES: 2 or 4), the
//! triangle count being a multiple of 3, and each filter's stride. Memory is bounded: the decoded size may not exceed [`MAX_RATIO`] times the
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

/// Decodes one view with `meshoptimizer-rs`, a safe-Rust port of meshoptimizer 1.3 (built
/// without its `simd` feature, so no `unsafe` code at all): the vertex codec (versions 0 and 1),
/// the triangle and sequence index codecs, then the view's filter. Malformed streams, counts that
/// the stream cannot hold, and filter words with no defined value (a zero-length octahedral
/// normal, a colour with a zero alpha scale) are errors of the crate, never a panic. Its filters
/// are meshoptimizer's scalar reference; the C++ decoder used before (its SSE build) rounds
/// exact halves to even instead and so differs by one unit in the last place on 0.14 % of the
/// octahedral normals of the test files (everything else byte-identical).
fn decode(c: &Compressed) -> Result<Vec<u8>, String> {
    use meshoptimizer_rs::codec;
    if c.count == 0 {
        return Ok(Vec::new());
    }
    let mut ws = meshoptimizer_rs::Workspace::new(meshoptimizer_rs::Limits::default());
    let (what, decoded) = match c.mode {
        Mode::Attributes => (
            "vertex",
            codec::decode_vertex_buffer(c.count, c.stride, c.source, &mut ws),
        ),
        Mode::Triangles => (
            "index",
            codec::decode_index_buffer(c.count, c.stride, c.source, &mut ws),
        ),
        Mode::Indices => (
            "index sequence",
            codec::decode_index_sequence(c.count, c.stride, c.source, &mut ws),
        ),
    };
    let mut out = decoded.map_err(|e| format!("corrupt {what} stream ({e})"))?;
    let (n, s) = (c.count, c.stride);
    let filtered = match c.filter {
        Filter::None => Ok(()),
        Filter::Octahedral => codec::decode_filter_oct(&mut out, n, s, &mut ws),
        Filter::Quaternion => codec::decode_filter_quat(&mut out, n, s, &mut ws),
        Filter::Exponential => codec::decode_filter_exp(&mut out, n, s, &mut ws),
        Filter::Color => codec::decode_filter_color(&mut out, n, s, &mut ws),
    };
    filtered.map_err(|e| format!("the {:?} filter failed ({e})", c.filter))?;
    Ok(out)
}
