//! Images: which image a texture shows (its core `source` or an extension's), and decoding every
//! used image up front, in parallel, before the materials are read.
//!
//! Source choice: `KHR_texture_basisu`'s KTX2 image (transcoded by `image_io::decode_ktx2`) or
//! `EXT_texture_webp`'s image when present — the extensions' intent is that a client that reads
//! them uses them — else the core `source` (PNG or JPEG, the fallback exporters write beside
//! them), else, when the only image is in a format Trayecto cannot decode (`MSFT_texture_dds`,
//! `EXT_texture_avif`), an error naming the extension and the texture. An extension image that
//! fails to decode is a warning and the magenta fallback, as any undecodable image is, rather than
//! a silent switch to the fallback image.
//!
//! Decoding is the slow part of loading a textured model (a PNG inflate per image); images are
//! independent, so they are decoded with rayon and stored by index. The results (and the order of
//! warnings, given when a material first uses a texture) do not depend on the thread count.

use std::sync::Arc;

use rayon::prelude::*;

use super::*;
use crate::scene::image_io::{decode_image, texture_from_image};

/// Image-source extensions whose formats Trayecto cannot decode, and what they hold.
const UNDECODABLE: &[(&str, &str)] = &[
    ("MSFT_texture_dds", "a DDS image"),
    ("EXT_texture_avif", "an AVIF image"),
];

/// One image after the decoding pass.
pub(super) enum Decoded {
    Image {
        name: String,
        image: Arc<image::DynamicImage>,
    },
    /// Unreadable or undecodable: the warning to give and the magenta fallback's name.
    Failed { warning: String, name: String },
    /// A path that leaves the scene's folder, or a malformed data URI: an error when used.
    Refused(SceneError),
}

/// Encoded bytes gathered (sequentially) for the parallel decode.
struct Pending<'a> {
    index: usize,
    name: String,
    bytes: std::borrow::Cow<'a, [u8]>,
    /// The warning if decoding fails: `{}` is replaced by the decoder's message.
    on_failure: String,
}

impl Loader<'_> {
    /// The image texture `t` shows, by the rule in this module's documentation.
    pub(super) fn texture_source(&self, t: &gltf::Texture) -> Result<usize, SceneError> {
        let images = self.doc.images().count();
        let ext_source = |ext: &str| -> Result<Option<usize>, SceneError> {
            let Some(v) = t.extension_value(ext) else {
                return Ok(None);
            };
            v.get("source")
                .and_then(|s| s.as_u64())
                .and_then(|s| usize::try_from(s).ok())
                .filter(|&s| s < images)
                .map(Some)
                .ok_or_else(|| {
                    self.err(format!(
                        "texture {}: {ext} 'source' names no image",
                        t.index()
                    ))
                })
        };
        for ext in ["KHR_texture_basisu", "EXT_texture_webp"] {
            if let Some(i) = ext_source(ext)? {
                return Ok(i);
            }
        }
        if let Some(img) = t.source() {
            return Ok(img.index());
        }
        for (ext, what) in UNDECODABLE {
            if let Some(i) = ext_source(ext)? {
                let name = self
                    .doc
                    .images()
                    .nth(i)
                    .and_then(|im| im.name().map(str::to_string))
                    .unwrap_or_else(|| format!("image {i}"));
                return Err(self.err(format!(
                    "texture {} ('{}'): its only image ('{name}') is {what} ({ext}), which Trayecto cannot decode; export the textures as PNG, JPEG or WebP, or with a PNG/JPEG fallback 'source'",
                    t.index(),
                    t.name().unwrap_or("unnamed"),
                )));
            }
        }
        Err(self.err(format!(
            "texture {} has no image 'source' (nor one Trayecto reads from an extension)",
            t.index()
        )))
    }

    /// Decodes every image a texture shows, in parallel, into `self.images`.
    pub(super) fn decode_images(&mut self) -> Result<(), SceneError> {
        let mut wanted: Vec<usize> = self
            .doc
            .textures()
            .filter_map(|t| self.texture_source(&t).ok())
            .collect();
        wanted.sort_unstable();
        wanted.dedup();
        let mut pending = Vec::new();
        let mut done = Vec::new();
        for i in wanted {
            let Some(img) = self.doc.images().nth(i) else {
                continue;
            };
            let name = img
                .name()
                .map(str::to_string)
                .unwrap_or_else(|| format!("image {i}"));
            match img.source() {
                gltf::image::Source::View { view, .. } => match self.view_bytes(&view) {
                    Ok(b) => pending.push(Pending {
                        index: i,
                        on_failure: format!(
                            "embedded image {i} ('{name}') could not be decoded ({{}}): using a magenta fallback"
                        ),
                        name,
                        bytes: b.into(),
                    }),
                    Err(e) => done.push((i, Decoded::Refused(e))),
                },
                gltf::image::Source::Uri { uri, .. } if uri.starts_with("data:") => {
                    match self.read_uri(uri, "image", i) {
                        Ok(b) => pending.push(Pending {
                            index: i,
                            on_failure: format!(
                                "image {i} could not be decoded ({{}}): using a magenta fallback"
                            ),
                            name,
                            bytes: b.into(),
                        }),
                        Err(e) => done.push((i, Decoded::Refused(e))),
                    }
                }
                gltf::image::Source::Uri { uri, .. } => {
                    let rel = crate::scene::image_io::percent_decode(uri);
                    match resolve_in_dir(self.dir, &rel) {
                        Err(why) => done.push((
                            i,
                            Decoded::Refused(self.err(format!("image {i}: {why}"))),
                        )),
                        Ok(path) => match crate::limits::read_file(&path) {
                            Ok(b) => pending.push(Pending {
                                index: i,
                                on_failure: format!(
                                    "texture '{rel}' could not be decoded ({{}}): using a magenta fallback"
                                ),
                                name: rel,
                                bytes: b.into(),
                            }),
                            Err(e) => done.push((
                                i,
                                Decoded::Failed {
                                    warning: format!(
                                        "texture '{rel}' could not be read ({e}): using a magenta fallback"
                                    ),
                                    name: rel,
                                },
                            )),
                        },
                    }
                }
            }
        }
        // The workers decode under this load's budget and cancel flag (crate::limits).
        let ctx = crate::limits::current();
        let decoded: Vec<(usize, Decoded)> = pending
            .into_par_iter()
            .map(|p| {
                let d = match crate::limits::scope(ctx.clone(), || decode_image(&p.name, &p.bytes))
                {
                    Ok(image) => Decoded::Image {
                        name: p.name,
                        image: Arc::new(image),
                    },
                    Err(e) => Decoded::Failed {
                        warning: p.on_failure.replace("{}", &e),
                        name: p.name,
                    },
                };
                (p.index, d)
            })
            .collect();
        self.images.extend(done);
        self.images.extend(decoded);
        Ok(())
    }

    /// The decoded image `index` as a texture (sRGB or linear); failures give their warning and
    /// the magenta fallback, refusals an error.
    pub(super) fn image_texture(
        &mut self,
        index: usize,
        srgb: bool,
    ) -> Result<crate::material::texture::Texture, SceneError> {
        let result = match self.images.get(&index) {
            Some(Decoded::Image { name, image }) => texture_from_image(name, image, srgb)
                .map_err(|e| (format!("image {index} ('{name}') could not be used ({e}): using a magenta fallback"), name.clone())),
            Some(Decoded::Failed { warning, name }) => Err((warning.clone(), name.clone())),
            Some(Decoded::Refused(_)) => {
                let Some(Decoded::Refused(e)) = self.images.remove(&index) else {
                    unreachable!("matched just above")
                };
                return Err(e);
            }
            None => return Err(self.err(format!("image {index} was not decoded"))),
        };
        Ok(match result {
            Ok(t) => t,
            Err((warning, name)) => {
                self.scene.warnings.push(warning);
                missing_texture(&name)
            }
        })
    }
}
