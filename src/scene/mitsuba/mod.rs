//! Mitsuba 3 scene files (`.xml`), read as Mitsuba 3's `xml.cpp` reads them: `<scene
//! version="…">` with objects (`shape`, `bsdf`, `texture`, `emitter`, `sensor`, `integrator`,
//! `medium`, …) nested or named by `id` and referenced with `<ref>`, properties (`float`,
//! `integer`, `boolean`, `string`, `rgb`, `spectrum`, `point`, `vector`, `transform`),
//! `<default>` parameters substituted for `$name` (the command line's `-D name=value` wins),
//! `<include>`, `<path>` search folders and `<alias>`. Files older than 2.0 (Mitsuba 0.6's
//! camelCase names, `lookAt`) are upgraded as Mitsuba 3 upgrades them.
//!
//! * This module reads the XML into an owned tree ([`Elem`]) with every include expanded and
//!   every parameter substituted; [`translate`] maps the objects onto the pbrt-v4 loader's
//!   directives ([`crate::scene::pbrt::embed`]), so materials, textures, lights, instancing and
//!   media are built by the same code as pbrt scenes. Which Mitsuba plugin becomes what, and
//!   where that is an approximation, is in [`translate`]'s documentation and in each scene's
//!   notes (`trayecto info`).
//! * Hostile files: the XML parser (roxmltree) refuses DTDs, so no entity is ever expanded
//!   (no "billion laughs"); nesting deeper than [`MAX_DEPTH`], more than [`MAX_NODES`]
//!   elements per file, more than [`MAX_INCLUDES`] includes or [`MAX_INCLUDED_BYTES`] of included
//!   text, include cycles and files larger than [`MAX_FILE_BYTES`] are errors naming the file
//!   and line. Every file is resolved with [`crate::image_io::resolve_in_dir`], the rule of every
//!   loader, and read through [`crate::limits`], whose budget the element tree is charged to.

mod serialized;
mod translate;

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use crate::scene::{Scene, SceneError};

/// Deepest element nesting accepted (Mitsuba's own scenes nest fewer than ten deep).
pub const MAX_DEPTH: usize = 64;
/// Most XML nodes one file may hold.
pub const MAX_NODES: u32 = 20_000_000;
/// Largest scene file accepted, in bytes.
pub const MAX_FILE_BYTES: u64 = 512 << 20;
/// Deepest `<include>` nesting.
pub const MAX_INCLUDE_DEPTH: usize = 32;
/// Most `<include>`d files one scene reads (counting repeats: a chain of files each including
/// the next twice reads 2ⁿ files without a cycle).
pub const MAX_INCLUDES: u32 = 10_000;
/// Most bytes one scene reads through `<include>`, all files together.
pub const MAX_INCLUDED_BYTES: u64 = 1 << 30;
/// What one element of the tree costs in memory beyond its text (the budget's estimate).
const ELEM_BYTES: u64 = 160;

/// One XML element with its include expanded and parameters substituted.
#[derive(Clone, Debug)]
pub(crate) struct Elem {
    pub tag: String,
    pub attrs: Vec<(String, String)>,
    pub children: Vec<Elem>,
    /// The file the element is in (for messages) and its line.
    pub file: Arc<str>,
    pub line: u32,
    /// The folder of the element's file, relative to the main file's folder ("" for the main
    /// file's own): files it names are looked up there first.
    pub dir: Arc<str>,
}

impl Elem {
    pub(crate) fn attr(&self, k: &str) -> Option<&str> {
        self.attrs
            .iter()
            .find(|(n, _)| n == k)
            .map(|(_, v)| v.as_str())
    }

    /// `file:line`.
    pub(crate) fn at(&self) -> String {
        format!("{}:{}", self.file, self.line)
    }
}

/// The command line's `-D name=value` parameters, for every Mitsuba file the process loads.
static DEFINES: std::sync::RwLock<Vec<(String, String)>> = std::sync::RwLock::new(Vec::new());

/// Sets `name=value` parameters for Mitsuba files (the command line's `-D`): they override the
/// files' `<default>`s in every later load.
pub fn set_defines(defines: Vec<(String, String)>) {
    if let Ok(mut d) = DEFINES.write() {
        *d = defines;
    }
}

/// Parses `NAME=VALUE` (the command line's `-D`).
pub fn parse_define(s: &str) -> Result<(String, String), String> {
    match s.split_once('=') {
        Some((n, v)) if !n.trim().is_empty() => Ok((n.trim().to_string(), v.to_string())),
        _ => Err(format!("'{s}' is not NAME=VALUE")),
    }
}

/// The [`crate::scene::FORMATS`] entry: the main file's bytes, its folder and its name.
pub fn load_from_file_bytes(bytes: &[u8], dir: &Path, label: &str) -> Result<Scene, SceneError> {
    let dir = if dir.as_os_str().is_empty() {
        PathBuf::from(".")
    } else {
        dir.to_path_buf()
    };
    load_impl(bytes, Some(dir), label)
}

/// Parses Mitsuba XML held in memory (the fuzzing entry point): nothing is read from disk, so
/// includes and file-backed shapes and textures are warnings.
pub fn load_from_bytes(bytes: &[u8], label: &str) -> Result<Scene, SceneError> {
    let mut scene = load_impl(bytes, None, label)?;
    scene.name = label.to_string();
    scene.source = Some(label.into());
    Ok(scene)
}

fn load_impl(bytes: &[u8], root: Option<PathBuf>, label: &str) -> Result<Scene, SceneError> {
    let text = utf8(bytes, label)?;
    let mut params: HashMap<String, String> = HashMap::new();
    if let Ok(d) = DEFINES.read() {
        params.extend(d.iter().cloned());
    }
    let mut r = Reader {
        root,
        params,
        search: Vec::new(),
        includes: 0,
        included_bytes: 0,
        stack: Vec::new(),
        warnings: Vec::new(),
    };
    if let Some(root) = &r.root
        && let Ok(c) = root
            .join(Path::new(label).file_name().unwrap_or_default())
            .canonicalize()
    {
        r.stack.push(c);
    }
    let mut root_elem = r.parse_document(text, label, "", 0)?;
    // Parameters are substituted once every <default> of every file is known.
    r.substitute_tree(&mut root_elem)?;
    let Reader {
        root,
        search,
        warnings,
        ..
    } = r;
    translate::translate(&root_elem, root, search, warnings, label)
}

fn utf8<'a>(bytes: &'a [u8], label: &str) -> Result<&'a str, SceneError> {
    std::str::from_utf8(bytes).map_err(|e| {
        SceneError::invalid(
            label,
            format!("the file is not UTF-8 text (byte {})", e.valid_up_to()),
        )
    })
}

/// Joins a folder prefix relative to the main file's folder and a name.
pub(crate) fn join(dir: &str, name: &str) -> String {
    if dir.is_empty() || name.starts_with('/') {
        name.to_string()
    } else {
        format!("{dir}/{name}")
    }
}

struct Reader {
    root: Option<PathBuf>,
    /// The command line's `-D` values, then each `<default>` not given before.
    params: HashMap<String, String>,
    /// `<path>` folders, relative to the main file's folder.
    search: Vec<String>,
    includes: u32,
    included_bytes: u64,
    stack: Vec<PathBuf>,
    warnings: Vec<String>,
}

/// Mitsuba 0.6 names (`toWorld`, `intIOR`, `sampleCount`) in Mitsuba 3's spelling.
fn snake_case(s: &str) -> String {
    // An underscore before a capital that follows a lower-case letter: `intIOR` is `int_ior`.
    let mut out = String::with_capacity(s.len() + 4);
    let mut prev_lower = false;
    for c in s.chars() {
        if c.is_ascii_uppercase() {
            if prev_lower {
                out.push('_');
            }
            out.push(c.to_ascii_lowercase());
        } else {
            out.push(c);
        }
        prev_lower = c.is_ascii_lowercase() || c.is_ascii_digit();
    }
    out
}

/// The major version of a `version="x.y.z"` attribute.
fn major_version(v: &str) -> Option<u32> {
    v.trim().split('.').next()?.parse().ok()
}

impl Reader {
    /// Parses one file into its `<scene>` element, includes expanded.
    fn parse_document(
        &mut self,
        text: &str,
        label: &str,
        dir: &str,
        include_depth: usize,
    ) -> Result<Elem, SceneError> {
        if text.len() as u64 > MAX_FILE_BYTES {
            return Err(SceneError::invalid(
                label,
                format!(
                    "the file is larger than {}",
                    crate::limits::bytes_text(MAX_FILE_BYTES)
                ),
            ));
        }
        let opts = roxmltree::ParsingOptions {
            allow_dtd: false,
            nodes_limit: MAX_NODES,
            ..Default::default()
        };
        let doc = roxmltree::Document::parse_with_options(text, opts).map_err(|e| {
            let pos = e.pos();
            let m = match e {
                roxmltree::Error::DtdDetected => {
                    "the file has a document type declaration (<!DOCTYPE …>); DTDs and their \
                     entities are refused"
                        .to_string()
                }
                roxmltree::Error::NodesLimitReached => {
                    format!("the file has more than {MAX_NODES} XML nodes")
                }
                e => format!("malformed XML: {e}"),
            };
            SceneError::invalid(format!("{label}:{}", pos.row), m)
        })?;
        let count = doc.descendants().count() as u64;
        crate::limits::charge(
            (text.len() as u64).saturating_add(count.saturating_mul(ELEM_BYTES)),
            || format!("the XML tree of {label}"),
        )
        .map_err(|e| SceneError::invalid(label, e.to_string()))?;
        let root = doc.root_element();
        let file: Arc<str> = Arc::from(label);
        let dir: Arc<str> = Arc::from(dir);
        let upgrade = root
            .attribute("version")
            .and_then(major_version)
            .is_some_and(|v| v < 2);
        if root.tag_name().name() != "scene" {
            return Err(SceneError::invalid(
                format!("{label}:1"),
                format!(
                    "the root element is <{}>; a Mitsuba scene file starts with <scene version=\"3.0.0\">",
                    root.tag_name().name()
                ),
            ));
        }
        if root.attribute("version").is_none() {
            self.warnings.push(format!(
                "{label}: <scene> has no version attribute; read as version 3"
            ));
        }
        self.convert(&doc, root, &file, &dir, 0, include_depth, upgrade)
    }

    #[allow(clippy::too_many_arguments)]
    fn convert(
        &mut self,
        doc: &roxmltree::Document,
        n: roxmltree::Node,
        file: &Arc<str>,
        dir: &Arc<str>,
        depth: usize,
        include_depth: usize,
        upgrade: bool,
    ) -> Result<Elem, SceneError> {
        let line = doc.text_pos_at(n.range().start).row;
        let at = format!("{file}:{line}");
        if depth > MAX_DEPTH {
            return Err(SceneError::invalid(
                at,
                format!("elements are nested more than {MAX_DEPTH} deep"),
            ));
        }
        let mut tag = n.tag_name().name().to_string();
        if upgrade && tag == "lookAt" {
            tag = "lookat".into();
        }
        let mut attrs = Vec::new();
        let now = matches!(n.tag_name().name(), "default" | "path" | "include");
        for a in n.attributes() {
            let mut v = if now {
                self.substitute(a.value(), &at)?
            } else {
                a.value().to_string()
            };
            if upgrade && a.name() == "name" {
                v = snake_case(&v);
            }
            attrs.push((a.name().to_string(), v));
        }
        let mut e = Elem {
            tag,
            attrs,
            children: Vec::new(),
            file: file.clone(),
            line,
            dir: dir.clone(),
        };
        for c in n.children().filter(|c| c.is_element()) {
            match c.tag_name().name() {
                "default" => {
                    let ce = self.convert(doc, c, file, dir, depth + 1, include_depth, upgrade)?;
                    match (ce.attr("name"), ce.attr("value")) {
                        // The first value given wins (the command line's, else the first
                        // <default>): an included file's defaults do not override the
                        // including file's.
                        (Some(name), Some(value)) => {
                            self.params
                                .entry(name.to_string())
                                .or_insert_with(|| value.to_string());
                        }
                        _ => {
                            return Err(SceneError::invalid(
                                ce.at(),
                                "<default> needs a name and a value",
                            ));
                        }
                    }
                }
                "path" => {
                    let ce = self.convert(doc, c, file, dir, depth + 1, include_depth, upgrade)?;
                    if let Some(v) = ce.attr("value") {
                        self.search.push(join(dir, v));
                    }
                }
                "include" => {
                    let ce = self.convert(doc, c, file, dir, depth + 1, include_depth, upgrade)?;
                    let included = self.include(&ce, include_depth)?;
                    e.children.extend(included);
                }
                _ => {
                    let ce = self.convert(doc, c, file, dir, depth + 1, include_depth, upgrade)?;
                    e.children.push(ce);
                }
            }
        }
        Ok(e)
    }

    fn substitute_tree(&self, e: &mut Elem) -> Result<(), SceneError> {
        let at = e.at();
        for (_, v) in &mut e.attrs {
            if v.contains('$') {
                *v = self.substitute(v, &at)?;
            }
        }
        for c in &mut e.children {
            self.substitute_tree(c)?;
        }
        Ok(())
    }

    /// Replaces `$name` by the parameter's value; an undefined parameter is an error.
    fn substitute(&self, v: &str, at: &str) -> Result<String, SceneError> {
        if !v.contains('$') {
            return Ok(v.to_string());
        }
        let mut out = String::with_capacity(v.len());
        let mut rest = v;
        while let Some(i) = rest.find('$') {
            out.push_str(&rest[..i]);
            let after = &rest[i + 1..];
            let len = after
                .find(|c: char| !(c.is_ascii_alphanumeric() || c == '_'))
                .unwrap_or(after.len());
            let name = &after[..len];
            if name.is_empty() {
                out.push('$');
            } else {
                match self.params.get(name) {
                    Some(val) => out.push_str(val),
                    None => {
                        return Err(SceneError::invalid(
                            at,
                            format!(
                                "parameter '${name}' is not defined (give it with -D {name}=VALUE or a <default name=\"{name}\" value=\"…\"/>)"
                            ),
                        ));
                    }
                }
            }
            rest = &after[len..];
        }
        out.push_str(rest);
        Ok(out)
    }

    /// `<include filename="…"/>`: the included file's `<scene>` children, in its place.
    fn include(&mut self, e: &Elem, include_depth: usize) -> Result<Vec<Elem>, SceneError> {
        let at = e.at();
        let Some(f) = e.attr("filename") else {
            return Err(SceneError::invalid(at, "<include> without a filename"));
        };
        let Some(root) = self.root.clone() else {
            self.warnings.push(format!(
                "{at}: include \"{f}\": files are not read when parsing text from memory"
            ));
            return Ok(Vec::new());
        };
        if include_depth + 1 > MAX_INCLUDE_DEPTH {
            return Err(SceneError::invalid(
                at,
                format!("include \"{f}\": includes nested more than {MAX_INCLUDE_DEPTH} deep"),
            ));
        }
        let (rel, path) = resolve(&root, &e.dir, &self.search, f)
            .map_err(|m| SceneError::invalid(&at, format!("include: {m}")))?;
        let canon = path.canonicalize().map_err(|err| SceneError::Io {
            path: format!("{at}: include \"{f}\""),
            error: err,
        })?;
        if self.stack.contains(&canon) {
            return Err(SceneError::invalid(
                at,
                format!("include \"{f}\" includes itself (an include cycle)"),
            ));
        }
        let size = std::fs::metadata(&path).map_or(0, |m| m.len());
        self.includes += 1;
        self.included_bytes = self.included_bytes.saturating_add(size);
        if self.includes > MAX_INCLUDES || self.included_bytes > MAX_INCLUDED_BYTES {
            return Err(SceneError::invalid(
                at,
                format!(
                    "include \"{f}\": the scene reads more than {MAX_INCLUDES} included files or {} of included text (files included many times over?)",
                    crate::limits::bytes_text(MAX_INCLUDED_BYTES)
                ),
            ));
        }
        if size > MAX_FILE_BYTES {
            return Err(SceneError::invalid(
                at,
                format!(
                    "include \"{f}\" is larger than {}",
                    crate::limits::bytes_text(MAX_FILE_BYTES)
                ),
            ));
        }
        let label = path.display().to_string();
        let bytes = crate::limits::read_file(&path).map_err(|err| SceneError::Io {
            path: label.clone(),
            error: err,
        })?;
        let text = utf8(&bytes, &label)?;
        let dir = Path::new(&rel)
            .parent()
            .map(|p| p.to_string_lossy().into_owned())
            .unwrap_or_default();
        self.stack.push(canon);
        let r = self.parse_document(text, &label, &dir, include_depth + 1);
        self.stack.pop();
        Ok(r?.children)
    }
}

/// Finds a file a scene names: beside the element's own file, then in the main file's folder,
/// then in each `<path>` folder (Mitsuba's file resolver order), every candidate resolved by
/// [`crate::image_io::resolve_in_dir`]. Returns the name relative to the main file's folder and
/// the path; when no candidate exists, the first refusal or "not found".
pub(crate) fn resolve(
    root: &Path,
    dir: &str,
    search: &[String],
    name: &str,
) -> Result<(String, PathBuf), String> {
    let mut candidates = vec![join(dir, name)];
    if !dir.is_empty() {
        candidates.push(name.to_string());
    }
    for s in search {
        candidates.push(join(s, name));
    }
    let mut first_err = None;
    for c in candidates {
        match crate::image_io::resolve_in_dir(root, &c) {
            Ok(p) if p.exists() => return Ok((c, p)),
            Ok(_) => {}
            Err(m) => {
                first_err.get_or_insert(m);
            }
        }
    }
    Err(first_err.unwrap_or_else(|| {
        let mut where_ = vec![format!("'{}'", root.display())];
        where_.extend(search.iter().map(|s| format!("'{s}'")));
        format!("'{name}' was not found (looked in {})", where_.join(", "))
    }))
}
