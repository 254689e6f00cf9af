//! Denoising with Intel Open Image Denoise (OIDN), loaded at run time (docs/DESIGN.md §5): the
//! build needs nothing, and `--denoise` without the library fails before rendering with the
//! command that installs it ([`INSTALL_COMMAND`]).
//!
//! The filter is OIDN's `RT` (ray-traced images) with `hdr = true` on the linear radiance, guided
//! by the albedo and normal AOVs ([`crate::film::aov::AovKind::Albedo`], `Normal`). The guides
//! are first denoised themselves, each with its own `RT` filter, and the main filter is told so
//! with `cleanAux = true` (OIDN's documentation, "Denoising with prefiltering": the highest
//! quality mode for final frames). The C API used is OIDN 2's (`oidnNewDevice`,
//! `oidnSetSharedFilterImage`, `oidnSetFilterBool`, …), declared here by hand because the library is
//! only opened with `dlopen` (the `libloading` crate).

use crate::film::Image;
use std::ffi::{CStr, CString, c_char, c_void};
use std::path::{Path, PathBuf};

/// The one command that installs OIDN where Trayecto looks for it.
pub const INSTALL_COMMAND: &str = "./scripts/install-oidn.sh";
/// The environment variable naming the library (like `--oidn PATH`).
pub const ENV_VAR: &str = "TRAYECTO_OIDN";

#[derive(Debug, thiserror::Error)]
pub enum DenoiseError {
    #[error(
        "--denoise needs Intel Open Image Denoise, which was not found (looked for {searched}); \
         install it with: {INSTALL_COMMAND} (or give --oidn PATH or {ENV_VAR}=PATH naming a \
         libOpenImageDenoise.so)"
    )]
    NotFound { searched: String },
    #[error(
        "{path}: no such file (given by {given}); install Open Image Denoise with: {INSTALL_COMMAND}, \
         or name an existing libOpenImageDenoise.so"
    )]
    Missing { path: PathBuf, given: &'static str },
    #[error(
        "{path}: cannot load Open Image Denoise: {message} (install a working copy with: {INSTALL_COMMAND})"
    )]
    Load { path: PathBuf, message: String },
    #[error("Open Image Denoise failed: {0}")]
    Oidn(String),
    #[error("denoising needs images of one size: {0}")]
    Size(String),
}

/// Where `--denoise` finds the library.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct DenoiseOptions {
    /// `--oidn PATH`: the library file (wins over [`ENV_VAR`] and the search).
    pub library: Option<PathBuf>,
}

// OIDN 2 C API constants (oidn.h).
const OIDN_DEVICE_TYPE_CPU: i32 = 1;
const OIDN_FORMAT_FLOAT3: i32 = 3;
const OIDN_ERROR_NONE: i32 = 0;

type Handle = *mut c_void;

/// The entry points used, resolved once when the library is opened.
struct Api {
    new_device: unsafe extern "C" fn(i32) -> Handle,
    set_device_int: unsafe extern "C" fn(Handle, *const c_char, i32),
    commit_device: unsafe extern "C" fn(Handle),
    get_device_error: unsafe extern "C" fn(Handle, *mut *const c_char) -> i32,
    release_device: unsafe extern "C" fn(Handle),
    new_filter: unsafe extern "C" fn(Handle, *const c_char) -> Handle,
    set_shared_filter_image: unsafe extern "C" fn(
        Handle,
        *const c_char,
        *mut c_void,
        i32,
        usize,
        usize,
        usize,
        usize,
        usize,
    ),
    set_filter_bool: unsafe extern "C" fn(Handle, *const c_char, bool),
    commit_filter: unsafe extern "C" fn(Handle),
    execute_filter: unsafe extern "C" fn(Handle),
    release_filter: unsafe extern "C" fn(Handle),
}

/// An opened OIDN library.
pub struct Oidn {
    api: Api,
    path: PathBuf,
    // Keeps the code behind `api`'s pointers mapped; dropped last.
    _lib: libloading::Library,
}

/// The library's file names, newest ABI first (a system install, the PyPI wheel).
const NAMES: [&str; 2] = ["libOpenImageDenoise.so.2", "libOpenImageDenoise.so"];

/// `pyoidn`'s layout inside a Python prefix: `lib/python3.X/site-packages/pyoidn/oidn/lib/`.
fn wheel_libs(prefix: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    let Ok(entries) = std::fs::read_dir(prefix.join("lib")) else {
        return out;
    };
    let mut dirs: Vec<PathBuf> = entries
        .flatten()
        .map(|e| e.path())
        .filter(|p| {
            p.file_name()
                .and_then(|n| n.to_str())
                .is_some_and(|n| n.starts_with("python3"))
        })
        .collect();
    dirs.sort();
    for d in dirs.into_iter().rev() {
        for site in ["site-packages", "dist-packages"] {
            out.push(d.join(site).join("pyoidn/oidn/lib/libOpenImageDenoise.so"));
        }
    }
    out
}

/// The places searched when neither `--oidn` nor [`ENV_VAR`] is given, in order: the project's
/// own install (`target/oidn-venv`, by [`INSTALL_COMMAND`]) beside the running binary, under
/// `$CARGO_TARGET_DIR` and under the current folder; the active virtual environment; the user's
/// and the system's Python site-packages; the system library folders. (The dynamic loader's own
/// search by name, `LD_LIBRARY_PATH` included, is tried after these.)
pub fn candidates() -> Vec<PathBuf> {
    let mut prefixes: Vec<PathBuf> = Vec::new();
    if let Ok(exe) = std::env::current_exe() {
        // target/{debug,release}/trayecto, or target/debug/deps/test-binary.
        for up in exe.ancestors().skip(1).take(3) {
            prefixes.push(up.join("oidn-venv"));
        }
    }
    if let Some(t) = std::env::var_os("CARGO_TARGET_DIR") {
        prefixes.push(PathBuf::from(t).join("oidn-venv"));
    }
    prefixes.push(PathBuf::from("target/oidn-venv"));
    if let Some(v) = std::env::var_os("VIRTUAL_ENV") {
        prefixes.push(PathBuf::from(v));
    }
    if let Some(home) = std::env::var_os("HOME") {
        prefixes.push(PathBuf::from(home).join(".local"));
    }
    prefixes.push(PathBuf::from("/usr/local"));
    prefixes.push(PathBuf::from("/usr"));
    let mut out: Vec<PathBuf> = prefixes.iter().flat_map(|p| wheel_libs(p)).collect();
    for dir in [
        "/usr/local/lib",
        "/usr/lib/x86_64-linux-gnu",
        "/usr/lib64",
        "/usr/lib",
    ] {
        for n in NAMES {
            out.push(Path::new(dir).join(n));
        }
    }
    out
}

impl Oidn {
    /// Opens the library: `explicit` (`--oidn`), else [`ENV_VAR`], else the first of
    /// [`candidates`] that exists, else the loader's search by name. A path that was given but
    /// does not exist is an error (it is not silently replaced by another copy).
    pub fn load(explicit: Option<&Path>) -> Result<Oidn, DenoiseError> {
        let given = match (explicit, std::env::var_os(ENV_VAR)) {
            (Some(p), _) => Some((p.to_path_buf(), "--oidn")),
            (None, Some(v)) if !v.is_empty() => Some((PathBuf::from(v), ENV_VAR)),
            _ => None,
        };
        if let Some((path, given)) = given {
            if !path.is_file() {
                return Err(DenoiseError::Missing { path, given });
            }
            return Self::open(&path);
        }
        let found = candidates().into_iter().find(|p| p.is_file());
        if let Some(p) = found {
            return Self::open(&p);
        }
        // A system install on the loader's path (LD_LIBRARY_PATH, ld.so.cache).
        for n in NAMES {
            if let Ok(o) = Self::open(Path::new(n)) {
                return Ok(o);
            }
        }
        Err(DenoiseError::NotFound {
            searched: format!(
                "--oidn, {ENV_VAR}, target/oidn-venv, Python site-packages (pyoidn) and the system \
                 library folders"
            ),
        })
    }

    fn open(path: &Path) -> Result<Oidn, DenoiseError> {
        let err = |m: String| DenoiseError::Load {
            path: path.to_path_buf(),
            message: m,
        };
        // SAFETY: loading a shared library runs its initialisers; OIDN's are the library's own.
        // This is the one way to use OIDN without a build-time dependency.
        let lib = unsafe { libloading::Library::new(path) }.map_err(|e| err(e.to_string()))?;
        macro_rules! sym {
            ($name:literal) => {
                // SAFETY: the symbol's type is OIDN 2's C declaration of it (oidn.h).
                *unsafe { lib.get($name) }.map_err(|e| err(e.to_string()))?
            };
        }
        let api = Api {
            new_device: sym!(b"oidnNewDevice\0"),
            set_device_int: sym!(b"oidnSetDeviceInt\0"),
            commit_device: sym!(b"oidnCommitDevice\0"),
            get_device_error: sym!(b"oidnGetDeviceError\0"),
            release_device: sym!(b"oidnReleaseDevice\0"),
            new_filter: sym!(b"oidnNewFilter\0"),
            set_shared_filter_image: sym!(b"oidnSetSharedFilterImage\0"),
            set_filter_bool: sym!(b"oidnSetFilterBool\0"),
            commit_filter: sym!(b"oidnCommitFilter\0"),
            execute_filter: sym!(b"oidnExecuteFilter\0"),
            release_filter: sym!(b"oidnReleaseFilter\0"),
        };
        Ok(Oidn {
            api,
            path: path.to_path_buf(),
            _lib: lib,
        })
    }

    /// The file the library was loaded from.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Denoises the linear HDR image `color` with the `albedo` and `normal` guides (prefiltered
    /// first), on OIDN's CPU device with `threads` threads (default: all). Returns a new image;
    /// the inputs are not changed.
    pub fn denoise(
        &self,
        color: &Image,
        albedo: &Image,
        normal: &Image,
        threads: Option<usize>,
    ) -> Result<Image, DenoiseError> {
        let (w, h) = (color.width as usize, color.height as usize);
        for (what, i) in [("albedo", albedo), ("normal", normal)] {
            if (i.width, i.height) != (color.width, color.height) {
                return Err(DenoiseError::Size(format!(
                    "colour {w}x{h}, {what} {}x{}",
                    i.width, i.height
                )));
            }
        }
        let flat =
            |i: &Image| -> Vec<f32> { i.data.iter().flat_map(|p| [p.x, p.y, p.z]).collect() };
        let mut c = flat(color);
        let mut a = flat(albedo);
        let mut n = flat(normal);
        let mut out = vec![0.0f32; c.len()];
        let device = Device::new(&self.api, threads)?;
        // Prefilter the guides in place, each with its own RT filter (input = output is allowed).
        for (name, buf) in [("albedo", &mut a), ("normal", &mut n)] {
            let f = device.filter()?;
            let p = buf.as_mut_ptr() as *mut c_void;
            f.image(name, p, w, h);
            f.image("output", p, w, h);
            f.run()?;
        }
        let f = device.filter()?;
        f.image("color", c.as_mut_ptr() as *mut c_void, w, h);
        f.image("albedo", a.as_mut_ptr() as *mut c_void, w, h);
        f.image("normal", n.as_mut_ptr() as *mut c_void, w, h);
        f.image("output", out.as_mut_ptr() as *mut c_void, w, h);
        f.set_bool("hdr", true);
        f.set_bool("cleanAux", true);
        f.run()?;
        drop(f);
        drop(device);
        Ok(Image {
            width: color.width,
            height: color.height,
            data: out
                .chunks_exact(3)
                .map(|v| crate::math::Vec3::new(v[0], v[1], v[2]))
                .collect(),
        })
    }
}

/// An OIDN device, released on drop.
struct Device<'a> {
    api: &'a Api,
    handle: Handle,
}

impl<'a> Device<'a> {
    fn new(api: &'a Api, threads: Option<usize>) -> Result<Device<'a>, DenoiseError> {
        // SAFETY: plain C calls on a handle this struct owns; names are NUL-terminated.
        let handle = unsafe { (api.new_device)(OIDN_DEVICE_TYPE_CPU) };
        if handle.is_null() {
            return Err(DenoiseError::Oidn("could not create a CPU device".into()));
        }
        let d = Device { api, handle };
        if let Some(t) = threads {
            unsafe { (api.set_device_int)(handle, c"numThreads".as_ptr(), t.min(1024) as i32) };
        }
        unsafe { (api.commit_device)(handle) };
        d.check()?;
        Ok(d)
    }

    /// The device's pending error, if any (OIDN reports errors per device, not per call).
    fn check(&self) -> Result<(), DenoiseError> {
        let mut msg: *const c_char = std::ptr::null();
        // SAFETY: OIDN writes a pointer to a NUL-terminated string it owns, valid until the next
        // call on the device; it is copied at once.
        let code = unsafe { (self.api.get_device_error)(self.handle, &mut msg) };
        if code == OIDN_ERROR_NONE {
            return Ok(());
        }
        let text = if msg.is_null() {
            format!("error code {code}")
        } else {
            unsafe { CStr::from_ptr(msg) }
                .to_string_lossy()
                .into_owned()
        };
        Err(DenoiseError::Oidn(text))
    }

    fn filter(&self) -> Result<Filter<'_, 'a>, DenoiseError> {
        // SAFETY: as in `new`.
        let handle = unsafe { (self.api.new_filter)(self.handle, c"RT".as_ptr()) };
        self.check()?;
        if handle.is_null() {
            return Err(DenoiseError::Oidn("could not create the RT filter".into()));
        }
        Ok(Filter {
            device: self,
            handle,
        })
    }
}

impl Drop for Device<'_> {
    fn drop(&mut self) {
        // SAFETY: the handle came from oidnNewDevice and every filter was released before.
        unsafe { (self.api.release_device)(self.handle) };
    }
}

/// An OIDN filter, released on drop.
struct Filter<'d, 'a> {
    device: &'d Device<'a>,
    handle: Handle,
}

impl Filter<'_, '_> {
    /// Shares a packed RGB float image (`w × h × 3` f32 at `data`) as the filter's `name` image.
    /// The buffer must outlive the filter's execution (the callers keep it alive).
    fn image(&self, name: &str, data: *mut c_void, w: usize, h: usize) {
        let name = CString::new(name).expect("image names have no NUL");
        // SAFETY: `data` points to w·h·3 f32s owned by the caller until after `run`; strides of 0
        // mean packed.
        unsafe {
            (self.device.api.set_shared_filter_image)(
                self.handle,
                name.as_ptr(),
                data,
                OIDN_FORMAT_FLOAT3,
                w,
                h,
                0,
                0,
                0,
            )
        };
    }

    fn set_bool(&self, name: &str, v: bool) {
        let name = CString::new(name).expect("parameter names have no NUL");
        // SAFETY: a plain C call on a live filter.
        unsafe { (self.device.api.set_filter_bool)(self.handle, name.as_ptr(), v) };
    }

    fn run(&self) -> Result<(), DenoiseError> {
        // SAFETY: the shared images are alive (see `image`).
        unsafe { (self.device.api.commit_filter)(self.handle) };
        self.device.check()?;
        unsafe { (self.device.api.execute_filter)(self.handle) };
        self.device.check()
    }
}

impl Drop for Filter<'_, '_> {
    fn drop(&mut self) {
        // SAFETY: the handle came from oidnNewFilter.
        unsafe { (self.device.api.release_filter)(self.handle) };
    }
}
