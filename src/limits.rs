//! The memory budget and the cancel flag every loader respects (docs/DESIGN.md §7, "Bounded
//! loads").
//!
//! A hostile file is small but names something huge: an image header claiming 100000² pixels, an
//! accessor count of 2²⁷, a compressed stream of zeros, a subdivision level that multiplies
//! triangles by 4096. Each decoder therefore works out what it is about to allocate from what it
//! knows *before* allocating, and asks the budget of the load in progress for it ([`charge`],
//! [`reserve`]). Over budget is a [`LimitError`] naming what asked and how much: never an abort.
//!
//! The budget and the cancel flag travel in a [`LoadContext`] installed for the current thread
//! ([`scope`]), so loader signatures need not carry them. Loaders that decode in parallel hand
//! [`current`] to their workers. Without a scope, a load gets a fresh budget of the
//! [`default_limit`]: half the physical memory, or half the address-space limit when the process
//! has one (`ulimit -v`), unless `--memory-limit` set another ([`set_default_limit`]).
//!
//! Budgets nest: the web server gives each job a budget whose charges also count against the
//! server's total ([`Budget::child`]); a job's charges return to the total when it ends.

use std::cell::RefCell;
use std::io::Read;
use std::path::Path;
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};

/// Why a load stopped before finishing.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum LimitError {
    /// The load asked for more memory than its budget has left.
    #[error(
        "{what} needs {} but the memory budget is {} ({} already in use; see --memory-limit)",
        bytes_text(*bytes),
        bytes_text(*limit),
        bytes_text(*used)
    )]
    OverBudget {
        what: String,
        bytes: u64,
        limit: u64,
        used: u64,
    },
    /// The load's cancel flag was raised (the web UI's Cancel, Ctrl-C).
    #[error("loading cancelled")]
    Cancelled,
}

impl From<LimitError> for String {
    fn from(e: LimitError) -> String {
        e.to_string()
    }
}

/// A byte count for messages: `1.5 GiB`, `120.0 MiB`, `512 bytes`.
pub fn bytes_text(b: u64) -> String {
    const K: f64 = 1024.0;
    let f = b as f64;
    if f >= K * K * K * K {
        format!("{:.1} TiB", f / (K * K * K * K))
    } else if f >= K * K * K {
        format!("{:.1} GiB", f / (K * K * K))
    } else if f >= K * K {
        format!("{:.1} MiB", f / (K * K))
    } else if f >= K {
        format!("{:.1} KiB", f / K)
    } else {
        format!("{b} bytes")
    }
}

/// Parses a memory size as `--memory-limit` takes it: a number of bytes, or a number with a unit
/// `K`, `M`, `G`, `T` (powers of 1024; `KiB`, `MB`, `GB`… mean the same), e.g. `4G`, `512M`,
/// `1.5GiB`.
pub fn parse_size(s: &str) -> Result<u64, String> {
    let t = s.trim();
    let split = t
        .find(|c: char| !(c.is_ascii_digit() || c == '.'))
        .unwrap_or(t.len());
    let (num, unit) = t.split_at(split);
    let value: f64 = num
        .parse()
        .map_err(|_| format!("'{s}' is not a size (e.g. 4G, 512M, 1073741824)"))?;
    let scale: f64 = match unit.trim().to_ascii_lowercase().as_str() {
        "" | "b" => 1.0,
        "k" | "kb" | "kib" => 1024.0,
        "m" | "mb" | "mib" => 1024.0 * 1024.0,
        "g" | "gb" | "gib" => 1024.0 * 1024.0 * 1024.0,
        "t" | "tb" | "tib" => 1024.0 * 1024.0 * 1024.0 * 1024.0,
        u => {
            return Err(format!(
                "unknown size unit '{u}' in '{s}' (use K, M, G or T)"
            ));
        }
    };
    let bytes = value * scale;
    if !(1024.0 * 1024.0..1e19).contains(&bytes) {
        return Err(format!("'{s}' is not a usable memory size (at least 1M)"));
    }
    Ok(bytes as u64)
}

/// A memory budget: what the loads charged to it so far, against its limit (and its parent's).
#[derive(Debug)]
pub struct Budget {
    limit: u64,
    used: AtomicU64,
    parent: Option<Arc<Budget>>,
}

impl Budget {
    pub fn new(limit: u64) -> Arc<Budget> {
        Arc::new(Budget {
            limit,
            used: AtomicU64::new(0),
            parent: None,
        })
    }

    /// A budget of `limit` whose charges also count against `parent` (a job inside a server's
    /// total); what it holds returns to the parent when it is dropped.
    pub fn child(parent: &Arc<Budget>, limit: u64) -> Arc<Budget> {
        Arc::new(Budget {
            limit,
            used: AtomicU64::new(0),
            parent: Some(parent.clone()),
        })
    }

    pub fn limit(&self) -> u64 {
        self.limit
    }

    pub fn used(&self) -> u64 {
        self.used.load(Ordering::Relaxed)
    }

    /// Adds `bytes` if this budget and every parent have room; else changes nothing and returns
    /// the budget that refused (its limit and use).
    fn try_add(&self, bytes: u64) -> Result<(), (u64, u64)> {
        let mut used = self.used.load(Ordering::Relaxed);
        loop {
            let next = used.saturating_add(bytes);
            if next > self.limit {
                return Err((self.limit, used));
            }
            match self
                .used
                .compare_exchange_weak(used, next, Ordering::Relaxed, Ordering::Relaxed)
            {
                Ok(_) => break,
                Err(now) => used = now,
            }
        }
        if let Some(p) = &self.parent
            && let Err(e) = p.try_add(bytes)
        {
            self.used.fetch_sub(bytes, Ordering::Relaxed);
            return Err(e);
        }
        Ok(())
    }

    /// [`Budget::try_add`], refused as the error that names `what` asked for `bytes`.
    fn charge(&self, bytes: u64, what: impl FnOnce() -> String) -> Result<(), LimitError> {
        self.try_add(bytes)
            .map_err(|(limit, used)| LimitError::OverBudget {
                what: what(),
                bytes,
                limit,
                used,
            })
    }

    fn release(&self, bytes: u64) {
        self.used.fetch_sub(bytes, Ordering::Relaxed);
        if let Some(p) = &self.parent {
            p.release(bytes);
        }
    }
}

impl Drop for Budget {
    fn drop(&mut self) {
        if let Some(p) = &self.parent {
            p.release(*self.used.get_mut());
        }
    }
}

/// Memory reserved from a budget for something transient (a decoder's intermediate buffer);
/// returned when dropped unless [`Reservation::keep`] makes it a lasting charge.
#[derive(Debug)]
#[must_use = "a reservation is returned when dropped"]
pub struct Reservation {
    budget: Arc<Budget>,
    bytes: u64,
}

impl Reservation {
    /// Reserves `bytes` more (tokens as a tokenizer makes them), with the same checks as
    /// [`LoadContext::reserve`]; on refusal what was held stays held until dropped.
    pub fn grow(&mut self, bytes: u64, what: impl FnOnce() -> String) -> Result<(), LimitError> {
        check_cancel()?;
        self.budget.charge(bytes, what)?;
        self.bytes += bytes;
        Ok(())
    }

    /// Keeps the memory charged for as long as the budget lives (data the scene holds).
    pub fn keep(mut self) {
        self.bytes = 0;
    }
}

impl Drop for Reservation {
    fn drop(&mut self) {
        if self.bytes > 0 {
            self.budget.release(self.bytes);
        }
    }
}

/// Asked by loaders whether to stop (the web UI's Cancel, Ctrl-C).
pub type CancelCheck = Arc<dyn Fn() -> bool + Send + Sync>;

/// Which files a scene may name (docs/DESIGN.md §7, "Confined paths"): the rule every loader
/// follows through `image_io::resolve_in_dir`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum PathRule {
    /// Only files inside the scene's folder: no `..`, no absolute paths, no symbolic links
    /// leading out. The server's rule for served and uploaded scenes, and the default of a load
    /// that does not say (a library user, a test).
    #[default]
    Confined,
    /// Whatever the file names, as pbrt-v4, Mitsuba and Blender read it: relative paths from
    /// the scene's folder (`..` included), absolute paths, symbolic links into asset libraries.
    /// The command line's rule: the user renders their own file.
    Open,
}

/// What a load runs under: its memory budget, its cancel flag and which files it may read.
#[derive(Clone)]
pub struct LoadContext {
    pub budget: Arc<Budget>,
    pub cancel: Option<CancelCheck>,
    pub paths: PathRule,
}

impl LoadContext {
    /// A context confined to the scene's folder ([`PathRule::Confined`]).
    pub fn new(budget: Arc<Budget>, cancel: Option<CancelCheck>) -> Arc<LoadContext> {
        LoadContext::with_paths(budget, cancel, PathRule::Confined)
    }

    /// A context reading scene-named files by `paths`.
    pub fn with_paths(
        budget: Arc<Budget>,
        cancel: Option<CancelCheck>,
        paths: PathRule,
    ) -> Arc<LoadContext> {
        Arc::new(LoadContext {
            budget,
            cancel,
            paths,
        })
    }

    /// A fresh budget of [`default_limit`], no cancel flag.
    pub fn with_default_budget() -> Arc<LoadContext> {
        LoadContext::new(Budget::new(default_limit()), None)
    }

    pub fn reserve(
        &self,
        bytes: u64,
        what: impl FnOnce() -> String,
    ) -> Result<Reservation, LimitError> {
        self.check_cancel()?;
        self.budget.charge(bytes, what)?;
        Ok(Reservation {
            budget: self.budget.clone(),
            bytes,
        })
    }

    pub fn check_cancel(&self) -> Result<(), LimitError> {
        match &self.cancel {
            Some(c) if c() => Err(LimitError::Cancelled),
            _ => Ok(()),
        }
    }
}

thread_local! {
    static CURRENT: RefCell<Option<Arc<LoadContext>>> = const { RefCell::new(None) };
}

/// Restores the previous context when a scope ends, also by a panic.
struct Restore(Option<Arc<LoadContext>>);

impl Drop for Restore {
    fn drop(&mut self) {
        let prev = self.0.take();
        CURRENT.with(|c| *c.borrow_mut() = prev);
    }
}

/// Runs `f` with `ctx` as this thread's load context.
pub fn scope<R>(ctx: Arc<LoadContext>, f: impl FnOnce() -> R) -> R {
    let prev = CURRENT.with(|c| c.borrow_mut().replace(ctx));
    let _restore = Restore(prev);
    f()
}

/// Runs `f` in the current context, or in a fresh one of the default budget when there is none
/// (a load started outside any scope: `trayecto info`, a test, a library user).
pub fn scope_or_default<R>(f: impl FnOnce() -> R) -> R {
    if CURRENT.with(|c| c.borrow().is_some()) {
        f()
    } else {
        scope(LoadContext::with_default_budget(), f)
    }
}

/// This thread's load context (for handing to parallel workers, which run [`scope`] with it);
/// a fresh default one outside any scope.
pub fn current() -> Arc<LoadContext> {
    CURRENT
        .with(|c| c.borrow().clone())
        .unwrap_or_else(LoadContext::with_default_budget)
}

/// The path rule of this thread's load (confined outside any scope).
pub fn path_rule() -> PathRule {
    CURRENT.with(|c| c.borrow().as_ref().map_or(PathRule::Confined, |c| c.paths))
}

fn with_current<R>(f: impl FnOnce(&LoadContext) -> R) -> R {
    let ctx = CURRENT.with(|c| c.borrow().clone());
    match ctx {
        Some(c) => f(&c),
        None => f(&LoadContext::with_default_budget()),
    }
}

/// Charges `bytes` to the current budget for data the scene keeps (texels, vertices, tokens).
/// `what` names the file and the thing, for the error.
pub fn charge(bytes: u64, what: impl FnOnce() -> String) -> Result<(), LimitError> {
    with_current(|c| c.reserve(bytes, what).map(Reservation::keep))
}

/// Reserves `bytes` of the current budget for a transient buffer, returned when the
/// reservation is dropped.
pub fn reserve(bytes: u64, what: impl FnOnce() -> String) -> Result<Reservation, LimitError> {
    with_current(|c| c.reserve(bytes, what))
}

/// Whether `bytes` more would fit in the current budget now (nothing is charged).
pub fn ensure_fits(bytes: u64, what: impl FnOnce() -> String) -> Result<(), LimitError> {
    reserve(bytes, what).map(drop)
}

/// `Err(Cancelled)` once the current load is cancelled. Cheap enough for every file read and
/// every few thousand iterations of a loop, not for every one.
pub fn check_cancel() -> Result<(), LimitError> {
    CURRENT.with(|c| match c.borrow().as_ref() {
        Some(ctx) => ctx.check_cancel(),
        None => Ok(()),
    })
}

/// Reads a whole file for a loader: only a regular file is opened (a FIFO or a device would
/// block or never end), the load's cancel flag is checked first and its size must fit in the
/// budget. Budget and cancel errors come back as `io::Error`s of kind `Other` carrying the
/// [`LimitError`], so loaders report them as any read error, naming the file.
pub fn read_file(path: &Path) -> std::io::Result<Vec<u8>> {
    check_cancel().map_err(std::io::Error::other)?;
    let meta = std::fs::metadata(path)?;
    if meta.is_dir() {
        return Err(std::io::Error::new(
            std::io::ErrorKind::IsADirectory,
            "is a folder, not a file",
        ));
    }
    if !meta.is_file() {
        return Err(std::io::Error::new(
            std::io::ErrorKind::InvalidInput,
            "is not a regular file (pipes, devices and sockets are not read)",
        ));
    }
    let len = meta.len();
    ensure_fits(len, || {
        format!("reading '{}' ({})", path.display(), bytes_text(len))
    })
    .map_err(std::io::Error::other)?;
    let mut out = Vec::with_capacity(len as usize);
    // A file growing while it is read stops at the size it had.
    std::fs::File::open(path)?.take(len).read_to_end(&mut out)?;
    Ok(out)
}

/// Reads a decompressing reader to its end, bounded twice: by `max_bytes` (what the compressed
/// input can honestly expand to: its size times the format's plausible ratio) and by the load's
/// budget, reserved as the output grows. `what` names the stream for the errors. The
/// reservation is returned with the bytes: the caller holds it while it uses them.
pub fn read_to_end_bounded(
    mut reader: impl Read,
    max_bytes: u64,
    what: &str,
) -> Result<(Vec<u8>, Reservation), String> {
    const STEP: usize = 1 << 20;
    let mut held = reserve(0, String::new)?;
    let mut out: Vec<u8> = Vec::new();
    loop {
        held.grow(STEP as u64, || {
            format!(
                "decompressing {what} (past {})",
                bytes_text(out.len() as u64)
            )
        })?;
        let start = out.len();
        out.resize(start + STEP, 0);
        let mut filled = start;
        while filled < out.len() {
            match reader.read(&mut out[filled..]) {
                Ok(0) => break,
                Ok(n) => filled += n,
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                Err(e) => return Err(format!("cannot decompress {what}: {e}")),
            }
        }
        out.truncate(filled);
        if out.len() as u64 > max_bytes {
            return Err(format!(
                "{what} decompresses to more than {} (more than its compressed size can plausibly hold)",
                bytes_text(max_bytes)
            ));
        }
        if filled < start + STEP {
            return Ok((out, held));
        }
    }
}

/// [`read_file`] as text (invalid UTF-8 is an `InvalidData` error).
pub fn read_to_string(path: &Path) -> std::io::Result<String> {
    String::from_utf8(read_file(path)?)
        .map_err(|_| std::io::Error::new(std::io::ErrorKind::InvalidData, "is not UTF-8 text"))
}

/// The process-wide default limit set by `--memory-limit` (0: work it out).
static DEFAULT_LIMIT: AtomicU64 = AtomicU64::new(0);

/// Sets the limit of budgets made without a scope (`--memory-limit`).
pub fn set_default_limit(bytes: u64) {
    DEFAULT_LIMIT.store(bytes, Ordering::Relaxed);
}

/// Used when neither `--memory-limit` nor the system says how much memory there is.
const FALLBACK_LIMIT: u64 = 4 << 30;

/// The default budget: `--memory-limit` if given, else half the physical memory, or half the
/// process's address-space limit when that is lower (under `ulimit -v` the allocator fails long
/// before physical memory is used up).
pub fn default_limit() -> u64 {
    let set = DEFAULT_LIMIT.load(Ordering::Relaxed);
    if set > 0 {
        return set;
    }
    let mut limit = physical_memory().map_or(FALLBACK_LIMIT, |m| m / 2);
    if let Some(a) = address_space_limit() {
        limit = limit.min(a / 2);
    }
    limit.max(64 << 20)
}

/// Total physical memory (Linux: `/proc/meminfo`).
fn physical_memory() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = text.lines().find(|l| l.starts_with("MemTotal:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib * 1024)
}

/// The soft address-space limit (`RLIMIT_AS`), if one is set (Linux: `/proc/self/limits`).
fn address_space_limit() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/self/limits").ok()?;
    let line = text.lines().find(|l| l.starts_with("Max address space"))?;
    line.split_whitespace().nth(3)?.parse().ok()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_parse_with_units() {
        assert_eq!(parse_size("4G").unwrap(), 4 << 30);
        assert_eq!(parse_size("512M").unwrap(), 512 << 20);
        assert_eq!(parse_size("1.5GiB").unwrap(), 3 << 29);
        assert_eq!(parse_size("2097152").unwrap(), 2 << 20);
        assert!(parse_size("0").is_err());
        assert!(parse_size("lots").is_err());
        assert!(parse_size("4X").is_err());
    }

    /// A child's charges count against its parent, a refusal changes neither, and what a
    /// child held returns to the parent when it is dropped.
    #[test]
    fn budgets_nest_and_release() {
        let total = Budget::new(100 << 20);
        let a = LoadContext::new(Budget::child(&total, 80 << 20), None);
        let b = LoadContext::new(Budget::child(&total, 80 << 20), None);
        a.reserve(60 << 20, || "a".into()).unwrap().keep();
        assert_eq!(total.used(), 60 << 20);
        // b's own limit has room, the total does not.
        let e = b.reserve(50 << 20, || "b's image".into()).err().unwrap();
        assert!(
            matches!(&e, LimitError::OverBudget { limit, .. } if *limit == 100 << 20),
            "{e}"
        );
        assert!(e.to_string().starts_with("b's image needs 50.0 MiB"), "{e}");
        assert_eq!((total.used(), b.budget.used()), (60 << 20, 0));
        {
            let _r = b.reserve(40 << 20, || "b".into()).unwrap();
            assert_eq!(total.used(), 100 << 20);
        }
        assert_eq!(total.used(), 60 << 20);
        drop(a);
        assert_eq!(total.used(), 0);
    }

    #[test]
    fn scopes_nest_and_cancel() {
        let flag = Arc::new(std::sync::atomic::AtomicBool::new(false));
        let f = flag.clone();
        let ctx = LoadContext::new(
            Budget::new(1 << 20),
            Some(Arc::new(move || f.load(Ordering::Relaxed))),
        );
        scope(ctx, || {
            assert!(check_cancel().is_ok());
            assert!(charge(2 << 20, || "x".into()).is_err());
            flag.store(true, Ordering::Relaxed);
            assert_eq!(check_cancel(), Err(LimitError::Cancelled));
            // A nested default scope keeps the outer context.
            scope_or_default(|| assert_eq!(check_cancel(), Err(LimitError::Cancelled)));
        });
        assert!(check_cancel().is_ok());
    }

    /// A FIFO is refused without opening it (opening would block until a writer appears).
    #[cfg(unix)]
    #[test]
    fn only_regular_files_are_read() {
        let dir = std::env::temp_dir().join(format!("trayecto-limits-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let fifo = dir.join("pipe");
        let _ = std::fs::remove_file(&fifo);
        let made = std::process::Command::new("mkfifo")
            .arg(&fifo)
            .status()
            .is_ok_and(|s| s.success());
        if made {
            let e = read_file(&fifo).unwrap_err();
            assert_eq!(e.kind(), std::io::ErrorKind::InvalidInput, "{e}");
        }
        std::fs::write(dir.join("f"), b"abc").unwrap();
        assert_eq!(read_file(&dir.join("f")).unwrap(), b"abc");
        let _ = std::fs::remove_dir_all(&dir);
    }
}
