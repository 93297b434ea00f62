//! Intel Open Image Denoise 2.x, loaded at run time.
//!
//! Debian 12 packages no OIDN 2, so the library comes from PyPI's `pyoidn`
//! wheel (`bash scripts/setup.sh` installs it into `target/venv-oidn`) or
//! from wherever the user has it. It is opened with `dlopen` when a render
//! asks for denoising: a build never needs it, every other command runs
//! without it, and a missing library is one line saying how to get it. A
//! crate that links OIDN would make the binary fail to start without it.
//!
//! The C API used (OIDN 2.x `oidn.h`; the same in 2.0 to 2.5):
//!
//! ```c
//! OIDNDevice oidnNewDevice(OIDNDeviceType type);                 // CPU = 1
//! void oidnSetDeviceInt(OIDNDevice, const char* name, int value);   // "numThreads"
//! void oidnSetDeviceBool(OIDNDevice, const char* name, bool value); // "setAffinity"
//! int  oidnGetDeviceInt(OIDNDevice, const char* name);              // "version"
//! void oidnCommitDevice(OIDNDevice);
//! OIDNError oidnGetDeviceError(OIDNDevice, const char** message);
//! void oidnReleaseDevice(OIDNDevice);
//! OIDNFilter oidnNewFilter(OIDNDevice, const char* type);        // "RT"
//! void oidnSetSharedFilterImage(OIDNFilter, const char* name, void* ptr,
//!     OIDNFormat format, size_t width, size_t height,
//!     size_t byteOffset, size_t pixelByteStride, size_t rowByteStride);
//! void oidnSetFilterBool(OIDNFilter, const char* name, bool value);  // "hdr", "cleanAux"
//! void oidnSetFilterInt(OIDNFilter, const char* name, int value);    // "quality"
//! void oidnCommitFilter(OIDNFilter);
//! void oidnExecuteFilter(OIDNFilter);
//! void oidnReleaseFilter(OIDNFilter);
//! ```
//!
//! The CPU device uses TBB through the soname `libtbb.so.12`, which this
//! process has already loaded (Debian's, through OpenVDB): the dynamic
//! linker binds OIDN to it, and both work (measured: the same output bits
//! as with the wheel's own TBB, at the same speed).

use std::ffi::{c_char, c_int, c_void, CStr, CString};
use std::path::{Path, PathBuf};
use std::ptr;

type Device = *mut c_void;
type Filter = *mut c_void;

const DEVICE_TYPE_CPU: c_int = 1;
const ERROR_NONE: c_int = 0;
const FORMAT_FLOAT3: c_int = 3;

/// OIDN's `quality` filter parameter.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Quality {
    High = 6,
    Balanced = 5,
    Fast = 4,
}

impl From<crate::scene::DenoiseQuality> for Quality {
    fn from(q: crate::scene::DenoiseQuality) -> Self {
        match q {
            crate::scene::DenoiseQuality::High => Quality::High,
            crate::scene::DenoiseQuality::Balanced => Quality::Balanced,
            crate::scene::DenoiseQuality::Fast => Quality::Fast,
        }
    }
}

/// The soname of OIDN 2.x (1.x is `.so.1`, with another API).
pub const SONAME: &str = "libOpenImageDenoise.so.2";
/// The library, or a folder holding it, when it is somewhere else.
pub const ENV_VAR: &str = "VDBPHOTON_OIDN";
/// What a render asking for denoising says when the library is missing.
pub const HOW_TO_GET: &str = "denoising needs Intel Open Image Denoise 2.x, which is not installed: run `bash scripts/setup.sh` (it installs PyPI's pyoidn into target/venv-oidn), or set VDBPHOTON_OIDN to a libOpenImageDenoise.so.2";

macro_rules! api {
    ($( $field:ident : fn($($arg:ty),*) $(-> $ret:ty)? ),* $(,)?) => {
        /// The functions of a loaded library.
        #[allow(non_snake_case)]
        struct Api {
            $( $field: unsafe extern "C" fn($($arg),*) $(-> $ret)?, )*
        }
        impl Api {
            /// # Safety
            /// `handle` is a live `dlopen` handle of an OIDN 2.x library.
            unsafe fn resolve(handle: *mut c_void, path: &Path) -> Result<Api, String> {
                Ok(Api {
                    $( $field: {
                        let name = concat!(stringify!($field), "\0");
                        // SAFETY: a NUL-terminated name and a live handle.
                        let sym = unsafe { libc::dlsym(handle, name.as_ptr().cast::<c_char>()) };
                        if sym.is_null() {
                            return Err(format!(
                                "'{}' has no function {} (not Open Image Denoise 2.x?)",
                                path.display(),
                                stringify!($field)
                            ));
                        }
                        // SAFETY: OIDN 2.x exports this function with this
                        // signature (oidn.h).
                        unsafe {
                            std::mem::transmute::<*mut c_void, unsafe extern "C" fn($($arg),*) $(-> $ret)?>(sym)
                        }
                    }, )*
                })
            }
        }
    };
}

api! {
    oidnNewDevice: fn(c_int) -> Device,
    oidnSetDeviceInt: fn(Device, *const c_char, c_int),
    oidnSetDeviceBool: fn(Device, *const c_char, bool),
    oidnGetDeviceInt: fn(Device, *const c_char) -> c_int,
    oidnCommitDevice: fn(Device),
    oidnGetDeviceError: fn(Device, *mut *const c_char) -> c_int,
    oidnReleaseDevice: fn(Device),
    oidnNewFilter: fn(Device, *const c_char) -> Filter,
    oidnSetSharedFilterImage: fn(Filter, *const c_char, *mut c_void, c_int, usize, usize, usize, usize, usize),
    oidnSetFilterBool: fn(Filter, *const c_char, bool),
    oidnSetFilterInt: fn(Filter, *const c_char, c_int),
    oidnCommitFilter: fn(Filter),
    oidnExecuteFilter: fn(Filter),
    oidnReleaseFilter: fn(Filter),
}

/// A loaded library and a committed CPU device on it. The library is never
/// closed: OIDN keeps its TBB threads for the process's life.
pub struct Oidn {
    api: Api,
    device: Device,
    /// Where it was loaded from.
    pub path: PathBuf,
    /// `major.minor.patch`.
    pub version: String,
}

// SAFETY: OIDN devices may be used from any thread, one call at a time;
// `denoise` takes `&self` and OIDN serialises a device's calls itself.
unsafe impl Send for Oidn {}
unsafe impl Sync for Oidn {}

impl Drop for Oidn {
    fn drop(&mut self) {
        // SAFETY: the device was created by this library and is released once.
        unsafe { (self.api.oidnReleaseDevice)(self.device) };
    }
}

/// Where the library is looked for, in order: `VDBPHOTON_OIDN` alone when
/// it is set (a file, or a folder holding the library); else beside the
/// executable, `../lib` from it, a `venv-oidn` with PyPI's `pyoidn` in the
/// executable's folder or up to three above it (`target/venv-oidn` for
/// `target/release/vdbphoton` and the test binaries in
/// `target/release/deps`), and last the bare soname (`LD_LIBRARY_PATH`,
/// the system's folders).
pub fn candidates() -> Vec<PathBuf> {
    let file_or_dir = |p: PathBuf| if p.is_dir() { p.join(SONAME) } else { p };
    if let Some(v) = std::env::var_os(ENV_VAR).filter(|v| !v.is_empty()) {
        return vec![file_or_dir(PathBuf::from(v))];
    }
    let mut out = Vec::new();
    if let Some(dir) = std::env::current_exe()
        .ok()
        .and_then(|e| e.parent().map(Path::to_path_buf))
    {
        out.push(dir.join(SONAME));
        out.push(dir.join("../lib").join(SONAME));
        for up in dir.ancestors().take(4) {
            let venv = up.join("venv-oidn").join("lib");
            if let Ok(entries) = std::fs::read_dir(&venv) {
                let mut found: Vec<PathBuf> = entries
                    .flatten()
                    .map(|e| e.path().join("site-packages/pyoidn/oidn/lib").join(SONAME))
                    .filter(|p| p.exists())
                    .collect();
                found.sort();
                out.extend(found);
            }
        }
    }
    out.push(PathBuf::from(SONAME));
    out
}

fn dlerror() -> String {
    // SAFETY: dlerror returns NULL or a NUL-terminated message.
    unsafe {
        let e = libc::dlerror();
        if e.is_null() {
            "unknown error".into()
        } else {
            CStr::from_ptr(e).to_string_lossy().into_owned()
        }
    }
}

impl Oidn {
    /// Opens the first candidate library that loads and has OIDN 2's API,
    /// and commits a CPU device with `threads` threads (0: every core).
    /// The error is one line: [`HOW_TO_GET`] when none was found.
    pub fn load(threads: usize) -> Result<Oidn, String> {
        let mut problems = Vec::new();
        for path in candidates() {
            let bare = path.as_os_str() == SONAME;
            if !bare && !path.exists() {
                continue;
            }
            let Ok(c) = CString::new(path.as_os_str().as_encoded_bytes()) else {
                continue;
            };
            // SAFETY: a NUL-terminated path; loading runs the library's
            // initialisers, which OIDN keeps to its own state.
            let handle = unsafe { libc::dlopen(c.as_ptr(), libc::RTLD_NOW | libc::RTLD_LOCAL) };
            if handle.is_null() {
                if !bare {
                    problems.push(format!("'{}': {}", path.display(), dlerror()));
                }
                continue;
            }
            // SAFETY: a live handle.
            let api = match unsafe { Api::resolve(handle, &path) } {
                Ok(api) => api,
                Err(e) => {
                    problems.push(e);
                    continue;
                }
            };
            return Self::with_device(api, path, threads);
        }
        Err(match problems.first() {
            None => HOW_TO_GET.to_string(),
            Some(p) => format!("{HOW_TO_GET} ({p})"),
        })
    }

    fn with_device(api: Api, path: PathBuf, threads: usize) -> Result<Oidn, String> {
        // SAFETY: the functions of a loaded OIDN 2 library, used as oidn.h
        // documents: parameters set before the commit, errors read after.
        unsafe {
            let device = (api.oidnNewDevice)(DEVICE_TYPE_CPU);
            if device.is_null() {
                return Err(format!(
                    "Open Image Denoise ('{}') could not create a CPU device: {}",
                    path.display(),
                    error(&api, ptr::null_mut()).unwrap_or_default()
                ));
            }
            (api.oidnSetDeviceInt)(
                device,
                c"numThreads".as_ptr(),
                threads.min(1 << 16) as c_int,
            );
            // Pinning threads to cores would fight rayon's workers.
            (api.oidnSetDeviceBool)(device, c"setAffinity".as_ptr(), false);
            (api.oidnCommitDevice)(device);
            let v = (api.oidnGetDeviceInt)(device, c"version".as_ptr());
            let me = Oidn {
                api,
                device,
                path,
                version: format!("{}.{}.{}", v / 10000, v / 100 % 100, v % 100),
            };
            me.check("creating its CPU device")?;
            Ok(me)
        }
    }

    /// The device's pending error, as one line naming what was being done.
    fn check(&self, what: &str) -> Result<(), String> {
        match error(&self.api, self.device) {
            None => Ok(()),
            Some(m) => Err(format!("Open Image Denoise failed {what}: {m}")),
        }
    }

    /// Denoises `color` (RGB, `width * height` pixels, row-major) with the
    /// RT filter for HDR images, guided by `albedo` when given (`clean_aux`:
    /// the guide has no noise to remove), into a new image.
    pub fn denoise(
        &self,
        color: &[[f32; 3]],
        albedo: Option<&[[f32; 3]]>,
        clean_aux: bool,
        width: usize,
        height: usize,
        quality: Quality,
    ) -> Result<Vec<[f32; 3]>, String> {
        let n = width * height;
        if color.len() != n || albedo.is_some_and(|a| a.len() != n) {
            return Err(format!(
                "denoising a {width} x {height} image needs {n} pixels per input"
            ));
        }
        let mut output = vec![[0.0f32; 3]; n];
        // SAFETY: the images are `n` packed RGB f32 pixels each and outlive
        // the filter, which is released before returning; OIDN reads color
        // and albedo and writes output.
        unsafe {
            let a = &self.api;
            let filter = (a.oidnNewFilter)(self.device, c"RT".as_ptr());
            if filter.is_null() {
                self.check("creating its RT filter")?;
                return Err("Open Image Denoise could not create its RT filter".into());
            }
            let set = |name: &CStr, p: *const [f32; 3]| {
                (a.oidnSetSharedFilterImage)(
                    filter,
                    name.as_ptr(),
                    p as *mut c_void,
                    FORMAT_FLOAT3,
                    width,
                    height,
                    0,
                    0,
                    0,
                )
            };
            set(c"color", color.as_ptr());
            if let Some(al) = albedo {
                set(c"albedo", al.as_ptr());
            }
            set(c"output", output.as_mut_ptr());
            (a.oidnSetFilterBool)(filter, c"hdr".as_ptr(), true);
            (a.oidnSetFilterBool)(filter, c"cleanAux".as_ptr(), clean_aux);
            (a.oidnSetFilterInt)(filter, c"quality".as_ptr(), quality as c_int);
            (a.oidnCommitFilter)(filter);
            let committed = self.check("preparing its filter");
            if committed.is_ok() {
                (a.oidnExecuteFilter)(filter);
            }
            (a.oidnReleaseFilter)(filter);
            committed?;
            self.check("denoising")?;
        }
        Ok(output)
    }
}

/// The pending error of `device` (NULL: of device creation), if any.
fn error(api: &Api, device: Device) -> Option<String> {
    let mut msg: *const c_char = ptr::null();
    // SAFETY: OIDN writes a pointer to its own NUL-terminated message.
    let code = unsafe { (api.oidnGetDeviceError)(device, &mut msg) };
    (code != ERROR_NONE).then(|| {
        let m = if msg.is_null() {
            String::new()
        } else {
            // SAFETY: a NUL-terminated string owned by OIDN.
            unsafe { CStr::from_ptr(msg) }
                .to_string_lossy()
                .into_owned()
        };
        format!("error {code}: {}", crate::image::one_line(&m))
    })
}
