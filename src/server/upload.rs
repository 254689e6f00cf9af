//! Uploads: a `.glb`, or a `.zip` of a glTF, pbrt or TOML scene folder, stored under
//! `uploads/` in the scenes folder so that it is listed and rendered like any other scene file.
//!
//! An archive is checked whole before anything is written, and then unpacked into a hidden
//! temporary folder that is renamed into place only when everything succeeded:
//! - every entry name is a relative path of plain components: no NUL, no backslash, no drive
//!   letter or root, no `.`/`..` (zip slip), no empty component, and the `zip` crate's own
//!   `enclosed_name` must accept it too; names may not repeat, and no file may stand where
//!   another entry needs a folder (`a` beside `a/b.txt`), both judged on the names the archive's
//!   central directory lists, raw (the `zip` crate keeps only the last of a repeated name);
//! - symbolic links (and any entry that is neither a file nor a folder) are refused, so nothing
//!   written can point outside the folder later;
//! - the number of entries, the total unpacked size and each large entry's compression ratio
//!   are capped (zip bombs), and the bytes actually unpacked are counted against the sizes the
//!   archive declares (an archive that lies about them is refused);
//! - `__MACOSX/` and hidden (dot) entries are skipped and reported;
//! - the result must hold at least one scene file.
//!
//! Nothing is ever overwritten: an upload whose name is taken is refused (409).

use std::io::{Cursor, Read, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

/// The folder under the scenes folder that uploads go to.
pub const UPLOAD_DIR: &str = "uploads";
const MAX_NAME: usize = 64;

/// Caps on one upload.
#[derive(Clone, Debug)]
pub struct UploadLimits {
    /// Bytes of the uploaded file itself (the request body).
    pub max_file: usize,
    /// Bytes of an archive's contents once unpacked, all entries together.
    pub max_unpacked: u64,
    pub max_entries: usize,
    /// Unpacked / packed size of any entry larger than [`RATIO_FLOOR`] bytes.
    pub max_ratio: u64,
}

/// Entries smaller than this are not ratio-checked (a small file of zeros compresses very well
/// and is harmless).
const RATIO_FLOOR: u64 = 1 << 20;

impl Default for UploadLimits {
    fn default() -> Self {
        UploadLimits {
            max_file: 128 << 20,
            max_unpacked: 1 << 30,
            max_entries: 2000,
            max_ratio: 200,
        }
    }
}

/// Why an upload was refused; the message names the entry at fault.
#[derive(Debug, thiserror::Error)]
pub enum UploadError {
    #[error("{0}")]
    Invalid(String),
    #[error("{0}")]
    TooLarge(String),
    #[error("'{0}' was already uploaded (uploads are never overwritten): rename the file")]
    Exists(String),
    #[error("could not store the upload: {0}")]
    Io(String),
}

/// What was stored.
#[derive(Debug)]
pub struct Stored {
    /// Scene files of the upload, as the scene list names them (`uploads/…`).
    pub scenes: Vec<String>,
    /// Entries left out (`__MACOSX/`, hidden files).
    pub skipped: Vec<String>,
}

fn invalid(m: impl Into<String>) -> UploadError {
    UploadError::Invalid(m.into())
}

/// A plain upload name: `STEM.glb` or `STEM.zip`, STEM of letters, digits, '-', '_' and '.',
/// not starting with '.'. Returns (stem, is_zip).
pub fn check_name(name: &str) -> Result<(String, bool), UploadError> {
    let lower = name.to_ascii_lowercase();
    let (stem, zip) = if lower.ends_with(".glb") {
        (&name[..name.len() - 4], false)
    } else if lower.ends_with(".zip") {
        (&name[..name.len() - 4], true)
    } else {
        return Err(invalid(
            "upload a .glb file, or a .zip of a folder holding a .gltf, .pbrt or .toml scene",
        ));
    };
    if stem.is_empty()
        || stem.len() > MAX_NAME
        || stem.starts_with('.')
        || !stem
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || matches!(c, '-' | '_' | '.'))
    {
        return Err(invalid(format!(
            "the file name must be at most {MAX_NAME} letters, digits, '-', '_' or '.' before \
             .glb/.zip, not starting with '.'"
        )));
    }
    Ok((stem.to_string(), zip))
}

/// The uploads folder inside the canonical `scenes_dir`, created if missing; refused if it is a
/// symlink or resolves elsewhere.
fn upload_root(scenes_dir: &Path) -> Result<PathBuf, UploadError> {
    let dir = scenes_dir.join(UPLOAD_DIR);
    match std::fs::symlink_metadata(&dir) {
        Ok(m) if m.is_dir() => {}
        Ok(_) => {
            return Err(UploadError::Io(format!(
                "'{UPLOAD_DIR}' in the scenes folder is not a plain folder"
            )));
        }
        Err(_) => std::fs::create_dir(&dir)
            .map_err(|e| UploadError::Io(format!("cannot create '{UPLOAD_DIR}': {e}")))?,
    }
    let canon = dir
        .canonicalize()
        .map_err(|e| UploadError::Io(format!("'{UPLOAD_DIR}': {e}")))?;
    if !canon.starts_with(scenes_dir) {
        return Err(UploadError::Io(format!(
            "'{UPLOAD_DIR}' resolves outside the scenes folder"
        )));
    }
    Ok(canon)
}

static TMP_COUNTER: AtomicU64 = AtomicU64::new(0);

fn temp_name(root: &Path, stem: &str) -> PathBuf {
    root.join(format!(
        ".upload-{}-{}-{stem}",
        std::process::id(),
        TMP_COUNTER.fetch_add(1, Ordering::Relaxed)
    ))
}

/// Stores an upload named `name` with contents `body` under `<scenes_dir>/uploads/`.
pub fn store(
    scenes_dir: &Path,
    name: &str,
    body: &[u8],
    limits: &UploadLimits,
) -> Result<Stored, UploadError> {
    let (stem, is_zip) = check_name(name)?;
    if body.len() > limits.max_file {
        return Err(UploadError::TooLarge(format!(
            "the file is larger than this server's upload limit of {} bytes",
            limits.max_file
        )));
    }
    let root = upload_root(scenes_dir)?;
    if is_zip {
        store_zip(scenes_dir, &root, &stem, body, limits)
    } else {
        store_glb(&root, &stem, body)
    }
}

fn store_glb(root: &Path, stem: &str, body: &[u8]) -> Result<Stored, UploadError> {
    if body.len() < 12 || &body[..4] != b"glTF" {
        return Err(invalid(
            "not a binary glTF file (a .glb starts with 'glTF'); for a .gltf with its files, \
             upload a .zip of its folder",
        ));
    }
    let file = format!("{stem}.glb");
    let dest = root.join(&file);
    if dest.exists() {
        return Err(UploadError::Exists(file));
    }
    let tmp = temp_name(root, stem);
    let io = |e: std::io::Error| UploadError::Io(e.to_string());
    let written = std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .open(&tmp)
        .and_then(|mut f| f.write_all(body).and_then(|_| f.sync_all()));
    // A hard link fails if the name exists, so a concurrent upload cannot be replaced.
    let linked = written.and_then(|_| std::fs::hard_link(&tmp, &dest));
    let _ = std::fs::remove_file(&tmp);
    match linked {
        Ok(()) => Ok(Stored {
            scenes: vec![format!("{UPLOAD_DIR}/{file}")],
            skipped: vec![],
        }),
        Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => Err(UploadError::Exists(file)),
        Err(e) => Err(io(e)),
    }
}

/// One archive entry, checked.
struct Entry {
    index: usize,
    /// Plain components.
    parts: Vec<String>,
    is_dir: bool,
    size: u64,
}

/// Splits and checks an entry name; `Ok(None)` for entries that are skipped.
fn entry_parts(raw: &[u8]) -> Result<Option<Vec<String>>, UploadError> {
    let shown = String::from_utf8_lossy(raw).replace('\0', "\\0");
    let bad = |why: &str| invalid(format!("archive entry '{shown}': {why}"));
    if raw.contains(&0) {
        return Err(bad("the name contains a NUL character"));
    }
    let name = std::str::from_utf8(raw).map_err(|_| bad("the name is not UTF-8"))?;
    if name.contains('\\') {
        return Err(bad("the name contains a backslash"));
    }
    if name.starts_with('/') {
        return Err(bad("absolute paths are not allowed"));
    }
    let trimmed = name.strip_suffix('/').unwrap_or(name);
    let mut parts = Vec::new();
    for p in trimmed.split('/') {
        match p {
            "" => return Err(bad("empty path component")),
            "." | ".." => {
                return Err(bad(
                    "'.' and '..' are not allowed (the path must stay inside the folder)",
                ));
            }
            p if p.contains(':') => return Err(bad("':' is not allowed (drive letters, streams)")),
            p if p.chars().any(|c| c.is_control()) => {
                return Err(bad("control characters are not allowed"));
            }
            p if p.len() > 255 => return Err(bad("a path component is longer than 255 bytes")),
            p => parts.push(p.to_string()),
        }
    }
    if parts.len() > 32 {
        return Err(bad("nested more than 32 folders deep"));
    }
    if parts[0] == "__MACOSX" || parts.iter().any(|p| p.starts_with('.')) {
        return Ok(None);
    }
    Ok(Some(parts))
}

/// The `n` bytes of `b` from `at`, or `None` when they are not all in it. Offsets come from the
/// archive itself (up to 2⁶⁴ − 1 in a Zip64 record), so the end is a checked sum.
fn field(b: &[u8], at: usize, n: usize) -> Option<&[u8]> {
    b.get(at..at.checked_add(n)?)
}

fn le16(b: &[u8], at: usize) -> Option<u64> {
    Some(u16::from_le_bytes(field(b, at, 2)?.try_into().ok()?) as u64)
}

fn le32(b: &[u8], at: usize) -> Option<u64> {
    Some(u32::from_le_bytes(field(b, at, 4)?.try_into().ok()?) as u64)
}

fn le64(b: &[u8], at: usize) -> Option<u64> {
    Some(u64::from_le_bytes(field(b, at, 8)?.try_into().ok()?))
}

/// The entry names exactly as the archive's central directory lists them, duplicates included
/// (APPNOTE.TXT §4.3.12 central directory headers, §4.3.16 end of central directory record,
/// §4.3.14–15 its Zip64 form). The `zip` crate indexes entries by name, so a repeated name
/// would otherwise be seen once, with the last entry's contents. `None` when the directory
/// cannot be walked (the archive is refused then).
fn raw_entry_names(body: &[u8], max_entries: usize) -> Option<Vec<Vec<u8>>> {
    const EOCD: [u8; 4] = *b"PK\x05\x06";
    const CENTRAL: [u8; 4] = *b"PK\x01\x02";
    // The end record is 22 bytes plus a comment of at most 65535 bytes, at the very end.
    let lo = body.len().saturating_sub(22 + 65535);
    let eocd = (lo..=body.len().checked_sub(22)?)
        .rev()
        .find(|&i| body[i..i + 4] == EOCD)?;
    let mut count = le16(body, eocd + 10)?;
    let mut size = le32(body, eocd + 12)?;
    let mut offset = le32(body, eocd + 16)?;
    if count == 0xffff || size == 0xffff_ffff || offset == 0xffff_ffff {
        // The Zip64 locator sits just before the end record and points at the Zip64 record.
        let loc = eocd.checked_sub(20)?;
        if body[loc..loc + 4] != *b"PK\x06\x07" {
            return None;
        }
        let rec = usize::try_from(le64(body, loc + 8)?).ok()?;
        if field(body, rec, 4)? != b"PK\x06\x06" {
            return None;
        }
        count = le64(body, rec + 32)?;
        size = le64(body, rec + 40)?;
        offset = le64(body, rec + 48)?;
    }
    if count > max_entries as u64 + 1 {
        // Over the limit either way; the caller says so with the real count.
        return Some(vec![Vec::new(); max_entries + 1]);
    }
    // Data prepended to the archive (a self-extractor) shifts every offset: the directory then
    // ends where the end record starts.
    let mut at = usize::try_from(offset).ok()?;
    if field(body, at, 4) != Some(&CENTRAL[..]) && count > 0 {
        at = eocd.checked_sub(usize::try_from(size).ok()?)?;
    }
    let mut names = Vec::with_capacity(count as usize);
    for _ in 0..count {
        if field(body, at, 4)? != CENTRAL {
            return None;
        }
        let name_len = le16(body, at + 28)? as usize;
        let extra_len = le16(body, at + 30)? as usize;
        let comment_len = le16(body, at + 32)? as usize;
        names.push(field(body, at + 46, name_len)?.to_vec());
        at += 46 + name_len + extra_len + comment_len;
    }
    Some(names)
}

/// Refuses an archive whose directory repeats a name or holds a file where another entry needs
/// a folder (`a` beside `a/b.txt`): unpacked, the one would replace or block the other. Names are
/// compared as [`entry_parts`] splits them, ignoring case (a case-insensitive file system would
/// merge them anyway); skipped entries (`__MACOSX/`, hidden) are never written and do not count.
fn check_raw_names(names: &[Vec<u8>]) -> Result<(), UploadError> {
    use std::collections::{HashMap, HashSet};
    let mut files: HashMap<String, String> = HashMap::new();
    let mut folders: HashMap<String, String> = HashMap::new();
    let mut explicit_folders = HashSet::new();
    for raw in names {
        let Some(parts) = entry_parts(raw)? else {
            continue;
        };
        let shown = String::from_utf8_lossy(raw).into_owned();
        let key = parts.join("/").to_lowercase();
        let is_dir = raw.ends_with(b"/");
        for i in 1..parts.len() {
            let folder = parts[..i].join("/").to_lowercase();
            folders.entry(folder).or_insert_with(|| shown.clone());
        }
        if is_dir {
            // A folder listed twice is harmless: both create the same folder.
            explicit_folders.insert(key.clone());
            folders.entry(key).or_insert(shown);
        } else if let Some(first) = files.insert(key, shown.clone()) {
            return Err(invalid(if first == shown {
                format!("archive entry '{shown}' appears twice")
            } else {
                format!(
                    "archive entry '{shown}' appears twice, as '{first}' too (names are compared \
                     ignoring case)"
                )
            }));
        }
    }
    for (key, file) in &files {
        if let Some(other) = folders.get(key) {
            return Err(invalid(format!(
                "archive entry '{file}' is a file, but '{other}' needs a folder of that name"
            )));
        }
    }
    Ok(())
}

/// Checks a `.zip` upload whole, writing nothing: what [`store`] does before it unpacks, the
/// entry point of the upload fuzz target. Returns the entries that would be written (as
/// '/'-separated paths) and those that would be skipped.
pub fn check_zip(
    body: &[u8],
    limits: &UploadLimits,
) -> Result<(Vec<String>, Vec<String>), UploadError> {
    let mut archive = zip::ZipArchive::new(Cursor::new(body))
        .map_err(|e| invalid(format!("not a readable zip archive: {e}")))?;
    let (entries, skipped) = check_archive(&mut archive, body, limits)?;
    Ok((entries.iter().map(|e| e.parts.join("/")).collect(), skipped))
}

/// Reads the archive's directory and checks every entry; nothing is written. `body` is the
/// archive's bytes, whose directory is also read raw ([`raw_entry_names`]).
fn check_archive<R: Read + std::io::Seek>(
    archive: &mut zip::ZipArchive<R>,
    body: &[u8],
    limits: &UploadLimits,
) -> Result<(Vec<Entry>, Vec<String>), UploadError> {
    let names = raw_entry_names(body, limits.max_entries).ok_or_else(|| {
        invalid("not a readable zip archive: its central directory cannot be walked")
    })?;
    let count = names.len().max(archive.len());
    if count > limits.max_entries {
        return Err(UploadError::TooLarge(format!(
            "the archive has {} entries, more than this server's limit of {}",
            count, limits.max_entries
        )));
    }
    check_raw_names(&names)?;
    if names.len() != archive.len() {
        return Err(invalid(format!(
            "the archive's directory lists {} entries but {} distinct names: a name appears twice",
            names.len(),
            archive.len()
        )));
    }
    let mut entries = Vec::new();
    let mut skipped = Vec::new();
    let mut total = 0u64;
    let mut seen = std::collections::HashSet::new();
    for index in 0..archive.len() {
        let f = archive
            .by_index_raw(index)
            .map_err(|e| invalid(format!("archive entry {index}: {e}")))?;
        let raw = f.name_raw().to_vec();
        let shown = String::from_utf8_lossy(&raw).replace('\0', "\\0");
        let Some(parts) = entry_parts(&raw)? else {
            skipped.push(shown);
            continue;
        };
        if f.enclosed_name().is_none() {
            return Err(invalid(format!(
                "archive entry '{shown}': the path leaves the folder"
            )));
        }
        let mode = f.unix_mode().unwrap_or(0);
        let kind = mode & 0o170000;
        if f.is_symlink() || kind == 0o120000 {
            return Err(invalid(format!(
                "archive entry '{shown}' is a symbolic link; links are not accepted"
            )));
        }
        if kind != 0 && kind != 0o100000 && kind != 0o040000 {
            return Err(invalid(format!(
                "archive entry '{shown}' is not a plain file or folder"
            )));
        }
        if f.encrypted() {
            return Err(invalid(format!(
                "archive entry '{shown}' is encrypted; upload an archive without a password"
            )));
        }
        let is_dir = f.is_dir();
        let size = if is_dir { 0 } else { f.size() };
        total = total.saturating_add(size);
        if total > limits.max_unpacked {
            return Err(UploadError::TooLarge(format!(
                "the archive unpacks to more than this server's limit of {} bytes",
                limits.max_unpacked
            )));
        }
        if size > RATIO_FLOOR && size / f.compressed_size().max(1) > limits.max_ratio {
            return Err(UploadError::TooLarge(format!(
                "archive entry '{shown}' is compressed {}:1, more than the {}:1 this server \
                 accepts (a zip bomb?)",
                size / f.compressed_size().max(1),
                limits.max_ratio
            )));
        }
        let key = parts.join("/").to_lowercase();
        if !is_dir && !seen.insert(key) {
            return Err(invalid(format!(
                "archive entry '{shown}' appears twice (names are compared ignoring case)"
            )));
        }
        entries.push(Entry {
            index,
            parts,
            is_dir,
            size,
        });
    }
    Ok((entries, skipped))
}

fn store_zip(
    scenes_dir: &Path,
    root: &Path,
    stem: &str,
    body: &[u8],
    limits: &UploadLimits,
) -> Result<Stored, UploadError> {
    let mut archive = zip::ZipArchive::new(Cursor::new(body))
        .map_err(|e| invalid(format!("not a readable zip archive: {e}")))?;
    let (entries, skipped) = check_archive(&mut archive, body, limits)?;
    let dest = root.join(stem);
    if std::fs::symlink_metadata(&dest).is_ok() {
        return Err(UploadError::Exists(stem.to_string()));
    }
    let tmp = temp_name(root, stem);
    std::fs::create_dir(&tmp).map_err(|e| UploadError::Io(e.to_string()))?;
    let result = unpack(&mut archive, &entries, &tmp, limits).and_then(|_| {
        let scenes = super::folder::list_scenes(&tmp);
        if scenes.is_empty() {
            return Err(invalid(format!(
                "the archive holds no scene file (expected {})",
                crate::scene::extension_list(false)
            )));
        }
        std::fs::rename(&tmp, &dest).map_err(|e| UploadError::Io(e.to_string()))?;
        Ok(scenes)
    });
    match result {
        Ok(scenes) => {
            let prefix = dest
                .strip_prefix(scenes_dir)
                .map(|p| p.to_string_lossy().replace(std::path::MAIN_SEPARATOR, "/"))
                .unwrap_or_default();
            Ok(Stored {
                scenes: scenes.iter().map(|s| format!("{prefix}/{s}")).collect(),
                skipped,
            })
        }
        Err(e) => {
            let _ = std::fs::remove_dir_all(&tmp);
            Err(e)
        }
    }
}

/// Writes the checked entries under `tmp` (a folder this upload created, so nothing in it is a
/// link), counting the bytes each really unpacks to.
fn unpack<R: Read + std::io::Seek>(
    archive: &mut zip::ZipArchive<R>,
    entries: &[Entry],
    tmp: &Path,
    limits: &UploadLimits,
) -> Result<(), UploadError> {
    let mut total = 0u64;
    for e in entries {
        let path = e.parts.iter().fold(tmp.to_path_buf(), |p, c| p.join(c));
        let shown = e.parts.join("/");
        let io = |err: std::io::Error| UploadError::Io(format!("'{shown}': {err}"));
        if e.is_dir {
            std::fs::create_dir_all(&path).map_err(io)?;
            continue;
        }
        if let Some(parent) = path.parent() {
            std::fs::create_dir_all(parent).map_err(io)?;
        }
        let mut f = archive
            .by_index(e.index)
            .map_err(|err| invalid(format!("archive entry '{shown}': {err}")))?;
        let mut out = std::fs::OpenOptions::new()
            .write(true)
            .create_new(true)
            .open(&path)
            .map_err(io)?;
        // One byte more than declared is read, to see whether the entry lies about its size.
        let copied = std::io::copy(&mut (&mut f).take(e.size + 1), &mut out)
            .map_err(|err| invalid(format!("archive entry '{shown}' cannot be unpacked: {err}")))?;
        if copied != e.size {
            return Err(invalid(format!(
                "archive entry '{shown}' unpacks to a different size than the archive declares"
            )));
        }
        total += copied;
        if total > limits.max_unpacked {
            return Err(UploadError::TooLarge(format!(
                "the archive unpacks to more than this server's limit of {} bytes",
                limits.max_unpacked
            )));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use zip::write::SimpleFileOptions;

    /// A fresh canonical scenes folder with a file beside it that must never be touched.
    fn scenes() -> PathBuf {
        let root = std::env::temp_dir().join(format!(
            "trayecto-upload-{}-{}",
            std::process::id(),
            TMP_COUNTER.fetch_add(1, Ordering::Relaxed)
        ));
        let _ = std::fs::remove_dir_all(&root);
        std::fs::create_dir_all(root.join("scenes")).unwrap();
        root.join("scenes").canonicalize().unwrap()
    }

    fn zip_of(entries: &[(&str, &[u8])]) -> Vec<u8> {
        let mut w = zip::ZipWriter::new(Cursor::new(Vec::new()));
        for (name, data) in entries {
            w.start_file(*name, SimpleFileOptions::default()).unwrap();
            w.write_all(data).unwrap();
        }
        w.finish().unwrap().into_inner()
    }

    const TOML: &[u8] = b"[camera]\nposition = [0, 0, 5]\n";

    /// Every file under `dir`, relative, sorted.
    fn tree(dir: &Path) -> Vec<String> {
        let mut out = Vec::new();
        let mut stack = vec![dir.to_path_buf()];
        while let Some(d) = stack.pop() {
            for e in std::fs::read_dir(&d).unwrap().flatten() {
                let p = e.path();
                if p.is_dir() {
                    stack.push(p);
                } else {
                    out.push(p.strip_prefix(dir).unwrap().display().to_string());
                }
            }
        }
        out.sort();
        out
    }

    fn refused(entries: &[(&str, &[u8])], expect: &str) {
        let dir = scenes();
        let before = tree(dir.parent().unwrap());
        let e = store(&dir, "x.zip", &zip_of(entries), &UploadLimits::default()).unwrap_err();
        assert!(e.to_string().contains(expect), "{e} (expected '{expect}')");
        // Nothing was written anywhere: no file beside or inside the scenes folder (the empty
        // uploads folder may exist).
        assert_eq!(tree(dir.parent().unwrap()), before);
        let _ = std::fs::remove_dir_all(dir.parent().unwrap());
    }

    #[test]
    fn a_scene_folder_archive_is_unpacked_under_uploads() {
        let dir = scenes();
        let s = store(
            &dir,
            "room.zip",
            &zip_of(&[
                ("room/scene.toml", TOML),
                ("room/meshes/a.obj", b"v 0 0 0\n"),
                ("__MACOSX/room/._scene.toml", b"junk"),
            ]),
            &UploadLimits::default(),
        )
        .unwrap();
        assert_eq!(
            s.scenes,
            [
                "uploads/room/room/meshes/a.obj",
                "uploads/room/room/scene.toml"
            ]
        );
        assert_eq!(s.skipped, ["__MACOSX/room/._scene.toml"]);
        assert_eq!(
            std::fs::read(dir.join("uploads/room/room/scene.toml")).unwrap(),
            TOML
        );
        // The same name again is refused, and the first upload is untouched.
        let e = store(
            &dir,
            "room.zip",
            &zip_of(&[("other.toml", TOML)]),
            &UploadLimits::default(),
        )
        .unwrap_err();
        assert!(matches!(e, UploadError::Exists(_)), "{e}");
        assert!(!dir.join("uploads/room/other.toml").exists());
        let _ = std::fs::remove_dir_all(dir.parent().unwrap());
    }

    #[test]
    fn a_glb_is_stored_and_never_overwritten() {
        let dir = scenes();
        let glb = b"glTF\x02\0\0\0\x0c\0\0\0";
        let s = store(&dir, "model.glb", glb, &UploadLimits::default()).unwrap();
        assert_eq!(s.scenes, ["uploads/model.glb"]);
        assert_eq!(std::fs::read(dir.join("uploads/model.glb")).unwrap(), glb);
        let e = store(
            &dir,
            "model.glb",
            b"glTFxxxxxxxxxxxx",
            &UploadLimits::default(),
        );
        assert!(matches!(e, Err(UploadError::Exists(_))));
        assert_eq!(std::fs::read(dir.join("uploads/model.glb")).unwrap(), glb);
        let e = store(
            &dir,
            "fake.glb",
            b"<html>not a model",
            &UploadLimits::default(),
        );
        assert!(e.unwrap_err().to_string().contains("not a binary glTF"));
        // Only the two stored files' folder content: no temporary left behind.
        assert_eq!(tree(&dir.join("uploads")), ["model.glb"]);
        let _ = std::fs::remove_dir_all(dir.parent().unwrap());
    }

    #[test]
    fn hostile_upload_names_are_refused() {
        for bad in [
            "../x.glb",
            "a/b.glb",
            "a\\b.zip",
            ".hidden.glb",
            "x.gltf",
            "x.exe",
            "nul\0.glb",
            ".glb",
            "é.zip",
        ] {
            assert!(check_name(bad).is_err(), "{bad:?}");
        }
        assert_eq!(
            check_name("Helmet-2.GLB").unwrap(),
            ("Helmet-2".into(), false)
        );
    }

    #[test]
    fn zip_slip_is_refused() {
        refused(
            &[("ok.toml", TOML), ("../../evil.toml", TOML)],
            "'.' and '..' are not allowed",
        );
        refused(&[("a/../../evil.toml", TOML)], "'.' and '..'");
        refused(&[("./a.toml", TOML)], "'.' and '..'");
    }

    #[test]
    fn absolute_and_odd_names_are_refused() {
        refused(&[("/tmp/evil.toml", TOML)], "absolute paths");
        refused(&[("C:/evil.toml", TOML)], "':' is not allowed");
        refused(&[("a\\..\\..\\evil.toml", TOML)], "backslash");
        refused(&[("a//b.toml", TOML)], "empty path component");
        refused(&[("a\nb.toml", TOML)], "control characters");
        refused(&[("x.toml", TOML), ("X.TOML", TOML)], "appears twice");
    }

    #[test]
    fn nul_in_a_name_is_refused() {
        // The writer refuses NUL in names, so the archive is patched after writing: the same
        // bytes in the local header and the central directory.
        let mut z = zip_of(&[("aaaa.toml", TOML)]);
        let mut n = 0;
        for i in 0..z.len() - 9 {
            if &z[i..i + 9] == b"aaaa.toml" {
                z[i + 1] = 0;
                n += 1;
            }
        }
        assert_eq!(n, 2);
        let dir = scenes();
        let e = store(&dir, "x.zip", &z, &UploadLimits::default()).unwrap_err();
        assert!(e.to_string().contains("NUL"), "{e}");
        let _ = std::fs::remove_dir_all(dir.parent().unwrap());
    }

    #[test]
    fn symlink_entries_are_refused() {
        let dir = scenes();
        let mut w = zip::ZipWriter::new(Cursor::new(Vec::new()));
        w.start_file("scene.toml", SimpleFileOptions::default())
            .unwrap();
        w.write_all(TOML).unwrap();
        w.add_symlink("link.toml", "/etc/passwd", SimpleFileOptions::default())
            .unwrap();
        let z = w.finish().unwrap().into_inner();
        let e = store(&dir, "x.zip", &z, &UploadLimits::default()).unwrap_err();
        assert!(e.to_string().contains("symbolic link"), "{e}");
        assert_eq!(tree(&dir), Vec::<String>::new());
        let _ = std::fs::remove_dir_all(dir.parent().unwrap());
    }

    #[test]
    fn zip_bombs_and_oversize_are_refused() {
        let zeros = vec![0u8; 8 << 20];
        // 8 MiB of zeros deflate to a few kB: over the ratio cap.
        refused(&[("scene.toml", TOML), ("big.bin", &zeros)], "zip bomb");
        // The total unpacked size, with the ratio check out of the way.
        let dir = scenes();
        let limits = UploadLimits {
            max_unpacked: 4 << 20,
            max_ratio: u64::MAX,
            ..UploadLimits::default()
        };
        let e = store(&dir, "x.zip", &zip_of(&[("big.toml", &zeros)]), &limits).unwrap_err();
        assert!(e.to_string().contains("unpacks to more than"), "{e}");
        // The file itself.
        let limits = UploadLimits {
            max_file: 100,
            ..UploadLimits::default()
        };
        let e = store(&dir, "x.zip", &zip_of(&[("a.toml", TOML)]), &limits).unwrap_err();
        assert!(matches!(e, UploadError::TooLarge(_)), "{e}");
        // Too many entries.
        let many: Vec<(String, &[u8])> = (0..30).map(|i| (format!("{i}.toml"), TOML)).collect();
        let many: Vec<(&str, &[u8])> = many.iter().map(|(n, d)| (n.as_str(), *d)).collect();
        let limits = UploadLimits {
            max_entries: 20,
            ..UploadLimits::default()
        };
        let e = store(&dir, "x.zip", &zip_of(&many), &limits).unwrap_err();
        assert!(e.to_string().contains("entries"), "{e}");
        assert_eq!(tree(&dir), Vec::<String>::new());
        let _ = std::fs::remove_dir_all(dir.parent().unwrap());
    }

    #[test]
    fn junk_and_truncated_archives_are_refused() {
        let mut w = zip::ZipWriter::new(Cursor::new(Vec::new()));
        let opts = SimpleFileOptions::default().compression_method(zip::CompressionMethod::Stored);
        w.start_file("scene.toml", opts).unwrap();
        w.write_all(TOML).unwrap();
        let z = w.finish().unwrap().into_inner();
        let dir = scenes();
        // Not a zip at all, and a truncated one.
        for junk in [&b"PK\x03\x04 garbage"[..], &z[..z.len() / 2]] {
            let e = store(&dir, "x.zip", junk, &UploadLimits::default()).unwrap_err();
            assert!(e.to_string().contains("not a readable zip"), "{e}");
        }
        assert_eq!(tree(&dir), Vec::<String>::new());
        let _ = std::fs::remove_dir_all(dir.parent().unwrap());
    }

    #[test]
    fn an_archive_without_a_scene_is_refused() {
        refused(&[("readme.txt", b"hello")], "holds no scene file");
    }

    #[test]
    fn a_symlinked_uploads_folder_is_refused() {
        let dir = scenes();
        let outside = dir.parent().unwrap().join("outside");
        std::fs::create_dir(&outside).unwrap();
        std::os::unix::fs::symlink(&outside, dir.join(UPLOAD_DIR)).unwrap();
        let e = store(
            &dir,
            "m.glb",
            b"glTF\x02\0\0\0\x0c\0\0\0",
            &UploadLimits::default(),
        )
        .unwrap_err();
        assert!(e.to_string().contains("not a plain folder"), "{e}");
        assert_eq!(tree(&outside), Vec::<String>::new());
        let _ = std::fs::remove_dir_all(dir.parent().unwrap());
    }
}
