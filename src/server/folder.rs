//! The scenes folder the server renders from: names resolved inside it (never outside, whatever
//! the symlinks say) and the lists of its scenes and environment maps. Used by the request
//! checks (`request.rs`), uploads (`upload.rs`) and the page's lists (`mod.rs`).

use std::path::{Component, Path, PathBuf};

/// The longest scene name a request or the page may give.
pub const MAX_SCENE_NAME: usize = 512;
/// How deep and how wide the scenes folder is listed, so a huge or looping tree cannot stall it.
const LIST_MAX_DEPTH: usize = 8;
const LIST_MAX_ENTRIES: usize = 5000;

fn has_scene_extension(p: &Path) -> bool {
    crate::scene::format_for(p).is_some()
}

/// Resolves a scene name relative to the (canonical) scenes folder. Refuses absolute paths, any
/// `..`/`.`/root component, backslashes and NULs before touching the file system, then
/// canonicalises (which resolves symlinks) and checks the result is still inside the folder.
pub fn resolve_scene(root: &Path, name: &str) -> Result<PathBuf, String> {
    let canon = resolve_in(root, name, "scene")?;
    if !has_scene_extension(&canon) {
        return Err(format!(
            "'{name}' is not a scene file (expected {})",
            crate::scene::extension_list(false)
        ));
    }
    Ok(canon)
}

/// Extensions of the environment maps the page offers (equirectangular images).
const ENV_EXTENSIONS: &[&str] = &["hdr", "exr"];

fn is_env_map(p: &Path) -> bool {
    p.extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| ENV_EXTENSIONS.contains(&e.to_ascii_lowercase().as_str()))
}

/// Resolves an environment map's name as [`resolve_scene`] resolves a scene's.
pub fn resolve_env(root: &Path, name: &str) -> Result<PathBuf, String> {
    let canon = resolve_in(root, name, "environment map")?;
    if !is_env_map(&canon) {
        return Err(format!(
            "'{name}' is not an environment map (expected .hdr or .exr)"
        ));
    }
    Ok(canon)
}

/// The path safety shared by scenes and environment maps; `what` names the kind in messages.
fn resolve_in(root: &Path, name: &str, what: &str) -> Result<PathBuf, String> {
    if name.contains('\0') || name.contains('\\') {
        return Err("may not contain backslashes or NUL characters".into());
    }
    let rel = Path::new(name);
    if rel.is_absolute() {
        return Err("must be a path relative to the scenes folder, not an absolute path".into());
    }
    for c in rel.components() {
        if !matches!(c, Component::Normal(_)) {
            return Err("may not contain '..' or '.' components".into());
        }
    }
    let canon = root
        .join(rel)
        .canonicalize()
        .map_err(|_| format!("no {what} '{name}' in the scenes folder"))?;
    if !canon.starts_with(root) {
        return Err("resolves outside the scenes folder".into());
    }
    if !canon.is_file() {
        return Err(format!("'{name}' is not a file"));
    }
    Ok(canon)
}

/// The page's scene list: scene files first (pbrt, glTF, FBX, TOML, OBJ, by path), then
/// standalone meshes (PLY); meshes that a pbrt or TOML file under the folder refers to only when
/// `all` (else they are counted in `hidden`).
pub fn scene_list(root: &Path, all: bool) -> (Vec<String>, usize) {
    let files = list_scenes(root);
    let referenced = referenced_files(root, &files);
    let rank = |f: &str| {
        let is_ref = referenced.contains(f);
        let mesh = crate::scene::format_for(Path::new(f)).is_some_and(|x| x.mesh_only);
        (is_ref as u8, mesh as u8)
    };
    let mut out: Vec<String> = files;
    let before = out.len();
    if !all {
        out.retain(|f| !referenced.contains(f));
    }
    let hidden = before - out.len();
    out.sort_by(|a, b| rank(a).cmp(&rank(b)).then_with(|| a.cmp(b)));
    (out, hidden)
}

/// Files of `files` that a pbrt or TOML scene among them names (as a quoted string, relative to
/// its own folder). Each scene file is read up to 16 MiB; a mention that is not a real reference
/// (a comment) only hides a mesh behind the "show all files" toggle.
fn referenced_files(root: &Path, files: &[String]) -> std::collections::HashSet<String> {
    const MAX_READ: u64 = 16 << 20;
    let listed: std::collections::HashSet<&str> = files.iter().map(|s| s.as_str()).collect();
    let mut out = std::collections::HashSet::new();
    for f in files {
        let ext = Path::new(f)
            .extension()
            .and_then(|e| e.to_str())
            .map(|e| e.to_ascii_lowercase());
        if !matches!(ext.as_deref(), Some("pbrt" | "toml")) {
            continue;
        }
        let path = root.join(f);
        if std::fs::metadata(&path).map_or(true, |m| m.len() > MAX_READ) {
            continue;
        }
        let Ok(text) = std::fs::read_to_string(&path) else {
            continue;
        };
        let dir = Path::new(f).parent().unwrap_or(Path::new(""));
        for quoted in text.split('"').skip(1).step_by(2) {
            if quoted.is_empty() || quoted.len() > MAX_SCENE_NAME || quoted.contains('\\') {
                continue;
            }
            // Normalise "a/./b" and "a/../b" lexically; stay inside the folder.
            let mut parts: Vec<&str> = dir
                .to_str()
                .unwrap_or("")
                .split('/')
                .filter(|p| !p.is_empty())
                .collect();
            let mut inside = true;
            for c in quoted.split('/') {
                match c {
                    "" | "." => {}
                    ".." => inside &= parts.pop().is_some(),
                    c => parts.push(c),
                }
            }
            let rel = parts.join("/");
            if inside && &rel != f && listed.contains(rel.as_str()) {
                out.insert(rel);
            }
        }
    }
    out
}

/// Scene files under the (canonical) scenes folder, as '/'-separated relative paths, sorted.
/// Hidden entries are skipped; symlinks are listed only if they are files that resolve inside
/// the folder (symlinked folders are not followed, so loops cannot occur).
pub fn list_scenes(root: &Path) -> Vec<String> {
    list_files(root, has_scene_extension, resolve_scene)
}

/// Environment maps (`.hdr`, `.exr`) under the scenes folder, listed as scenes are.
pub fn list_environments(root: &Path) -> Vec<String> {
    list_files(root, is_equirect_image, resolve_env)
}

/// Whether `p` is an environment map by its content, not only its extension: an .hdr/.exr image
/// twice as wide as high (the equirectangular layout the page's environment option reads).
/// Reference renders and other pictures kept beside the scenes are left out of the list; only
/// the header is read.
fn is_equirect_image(p: &Path) -> bool {
    is_env_map(p)
        && crate::image_io::image_dimensions(p)
            .is_some_and(|(w, h)| h > 0 && w.abs_diff(2 * h) <= 1)
}

fn list_files(
    root: &Path,
    wanted: fn(&Path) -> bool,
    resolve: fn(&Path, &str) -> Result<PathBuf, String>,
) -> Vec<String> {
    let mut out = Vec::new();
    let mut seen = 0usize;
    let mut stack: Vec<(PathBuf, usize)> = vec![(root.to_path_buf(), 0)];
    while let Some((dir, depth)) = stack.pop() {
        let Ok(entries) = std::fs::read_dir(&dir) else {
            continue;
        };
        for e in entries.flatten() {
            seen += 1;
            if seen > LIST_MAX_ENTRIES {
                break;
            }
            let name = e.file_name();
            let Some(name) = name.to_str() else { continue };
            if name.starts_with('.') {
                continue;
            }
            let path = e.path();
            let Ok(meta) = std::fs::symlink_metadata(&path) else {
                continue;
            };
            if meta.is_dir() {
                if depth + 1 < LIST_MAX_DEPTH {
                    stack.push((path, depth + 1));
                }
                continue;
            }
            let Ok(rel) = path.strip_prefix(root) else {
                continue;
            };
            let Some(rel) = rel.to_str() else { continue };
            if !wanted(&path) {
                continue;
            }
            if meta.file_type().is_symlink() {
                // Listed only if resolving it would be accepted.
                if resolve(root, rel).is_err() {
                    continue;
                }
            } else if !meta.is_file() {
                continue;
            }
            out.push(rel.replace(std::path::MAIN_SEPARATOR, "/"));
        }
    }
    out.sort();
    out
}
