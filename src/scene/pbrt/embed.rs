//! The pbrt-v4 loader driven by another front end: a translator (the Mitsuba XML loader) runs
//! pbrt directives it generates, each located at the line of its own file that caused it, and
//! hands over geometry, lights and media it has already decoded. The graphics state, material
//! and texture mapping, area lights, instancing and finishing are the pbrt loader's own, so a
//! translated scene renders exactly as the equivalent `.pbrt` file would.

use std::path::PathBuf;

use super::params::{Param, ParamList, Values};
use super::{Cursor, Loader, tokenizer};
use crate::scene::{LightDesc, MediumDesc, Scene, SceneError};

pub(crate) struct Builder {
    l: Loader,
}

impl Builder {
    /// `root_dir`: the folder files are resolved in ([`crate::image_io::resolve_in_dir`]); `None`
    /// reads nothing from disk.
    pub(crate) fn new(root_dir: Option<PathBuf>) -> Builder {
        Builder {
            l: Loader::new(root_dir),
        }
    }

    /// Runs pbrt directives written as text; messages name `file:line`.
    pub(crate) fn run(&mut self, text: &str, file: &str, line: u32) -> Result<(), SceneError> {
        let at = format!("{file}:{line}");
        let (mut tokens, _held) = tokenizer::tokenize(text)
            .map_err(|(_, m)| SceneError::invalid(&at, format!("(translated) {m}")))?;
        for t in &mut tokens {
            t.line = line;
        }
        let mut p = Cursor {
            tokens: &tokens,
            pos: 0,
            file,
            warnings: Vec::new(),
        };
        while let Some(tok) = p.next() {
            let tokenizer::TokenKind::Word(name) = &tok.kind else {
                return Err(SceneError::invalid(
                    &at,
                    "(translated) expected a directive",
                ));
            };
            let name = name.clone();
            self.l.directive(&name, &mut p, &at, 0)?;
            self.l.scene.warnings.append(&mut p.warnings);
        }
        Ok(())
    }

    /// How the camera is fitted to an image of another shape than its film (the translator's
    /// sensor convention, where it is not pbrt-v4's); the camera is made with the film, later.
    pub(crate) fn set_camera_fit(&mut self, fit: crate::scene::SensorFit) {
        self.l.camera_fit = Some(fit);
    }

    /// A `trianglemesh` shape from decoded arrays (pbrt's uv convention: v up).
    pub(crate) fn triangle_mesh(
        &mut self,
        positions: &[f32],
        indices: &[u32],
        normals: Option<&[f32]>,
        uvs: Option<&[f32]>,
        alpha: Option<&str>,
        at: &str,
    ) -> Result<(), SceneError> {
        let nums = |v: &[f32]| Values::Nums(v.iter().map(|&x| f64::from(x)).collect());
        let mut list = ParamList::default();
        let mut add = |decl: &str, values: Values| -> Result<(), SceneError> {
            let p = Param::new(decl, values).map_err(|m| SceneError::invalid(at, m))?;
            list.push(p).map_err(|m| SceneError::invalid(at, m))
        };
        add("point3 P", nums(positions))?;
        add(
            "integer indices",
            Values::Nums(indices.iter().map(|&i| f64::from(i)).collect()),
        )?;
        if let Some(n) = normals {
            add("normal N", nums(n))?;
        }
        if let Some(uv) = uvs {
            add("point2 uv", nums(uv))?;
        }
        if let Some(a) = alpha {
            add("texture alpha", Values::Strs(vec![a.to_string()]))?;
        }
        let list = self.l.with_attributes(list, "shape");
        self.l.shape("trianglemesh", list, at)
    }

    /// A light that is not an area light, in world space.
    pub(crate) fn light(&mut self, l: LightDesc) {
        self.l.scene.lights.push(l);
    }

    /// A named medium (`MediumInterface` and the camera name it).
    pub(crate) fn medium(&mut self, name: &str, m: MediumDesc) {
        let id = self.l.scene.add_medium(m);
        self.l.media.insert(name.to_string(), Some(id));
    }

    /// The samples per pixel the file asks for.
    pub(crate) fn set_spp(&mut self, n: u32) {
        self.l.scene.hints.spp = Some(n.clamp(1, 1 << 20));
    }

    pub(crate) fn warn(&mut self, w: String) {
        self.l.warn(w);
    }

    pub(crate) fn finish(self) -> Result<Scene, SceneError> {
        self.l.finish()
    }
}
