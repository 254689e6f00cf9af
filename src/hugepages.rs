//! A global allocator that puts large allocations on transparent huge pages (2 MiB on x86-64).
//!
//! Why: a path vertex on a real model reads memory scattered over tens of megabytes (ToyCar:
//! ~22 MB of texels in seven textures, 6.3 MB of BVH nodes, 5 MB of leaf triangles, the mesh
//! attributes), every access at an unrelated address. With 4 KiB pages nearly every one of those
//! accesses needs its own TLB entry, and the second-level TLB (a few thousand entries, 8–12 MB of
//! 4 KiB pages) cannot hold them, so each costs a page walk on top of its cache miss. One 2 MiB
//! entry covers 512 of those pages. Linux gives an anonymous mapping huge pages when asked with
//! `madvise(MADV_HUGEPAGE)` (transparent huge pages in `madvise` mode, a common default) and
//! only maps one where a whole 2 MiB-aligned block lies inside the mapping, so large allocations
//! here are their own 2 MiB-aligned mappings whose length is a multiple of 2 MiB.
//!
//! It changes where bytes live, never what they are: images are bit-identical. Small
//! allocations (below [`THRESHOLD`]) go to the system allocator unchanged. An allocation of
//! `n ≥ THRESHOLD` bytes takes `n` rounded up to 2 MiB (less than double `n`; on average about
//! 1 MiB more per large allocation, and a render has a few dozen). `TRAYECTO_HUGEPAGES=0` in the
//! environment turns it off (read once, for measuring). Where the kernel refuses the advice the
//! memory is ordinary 4 KiB pages, as without this allocator. Elsewhere than Linux it is the
//! system allocator.
//!
//! The binary installs it (`#[global_allocator]` in `src/bin/trayecto/main.rs`); a program using
//! the library may do the same.

use std::alloc::{GlobalAlloc, Layout, System};

/// The huge page size the mappings are aligned to and sized in (x86-64 and aarch64 with 4 KiB
/// base pages).
pub const HUGE_PAGE: usize = 2 << 20;

/// Allocations of at least this many bytes get their own huge-page mapping.
pub const THRESHOLD: usize = 1 << 20;

/// The allocator: see the module documentation.
pub struct HugePageAlloc;

#[cfg(target_os = "linux")]
mod imp {
    use super::HUGE_PAGE;
    use std::sync::atomic::{AtomicU8, Ordering};

    /// 0: not read yet, 1: on, 2: off (`TRAYECTO_HUGEPAGES=0`).
    static STATE: AtomicU8 = AtomicU8::new(0);

    /// Whether huge-page mappings are on. Reads the environment through `getenv`, which does
    /// not allocate (this runs inside the allocator).
    pub fn enabled() -> bool {
        match STATE.load(Ordering::Relaxed) {
            1 => true,
            2 => false,
            _ => {
                // SAFETY: `getenv` with a NUL-terminated name; the result is only read as a C
                // string while no other thread changes the environment (Rust's `set_var` is
                // itself `unsafe` for that reason, and Trayecto never calls it).
                let off = unsafe {
                    let v = libc::getenv(c"TRAYECTO_HUGEPAGES".as_ptr());
                    !v.is_null() && std::ffi::CStr::from_ptr(v).to_bytes() == b"0"
                };
                STATE.store(if off { 2 } else { 1 }, Ordering::Relaxed);
                !off
            }
        }
    }

    /// The mapping length of a large allocation of `size` bytes.
    pub fn mapped_len(size: usize) -> usize {
        size.div_ceil(HUGE_PAGE) * HUGE_PAGE
    }

    /// A fresh, zeroed, `HUGE_PAGE`-aligned read-write mapping of `mapped_len(size)` bytes
    /// advised for huge pages, or null.
    pub fn map(size: usize) -> *mut u8 {
        let len = mapped_len(size);
        let Some(over) = len.checked_add(HUGE_PAGE) else {
            return std::ptr::null_mut();
        };
        // SAFETY: an anonymous private mapping at an address of the kernel's choice touches no
        // existing memory. Over-mapping by one huge page and unmapping the unaligned head and
        // the tail leaves exactly [start, start + len), 2 MiB-aligned (mmap gives 4 KiB
        // alignment only). `madvise` only changes how that range is backed; if it fails the
        // range is ordinary pages, which is still correct.
        unsafe {
            let p = libc::mmap(
                std::ptr::null_mut(),
                over,
                libc::PROT_READ | libc::PROT_WRITE,
                libc::MAP_PRIVATE | libc::MAP_ANONYMOUS,
                -1,
                0,
            );
            if p == libc::MAP_FAILED {
                return std::ptr::null_mut();
            }
            let base = p as usize;
            let start = base.next_multiple_of(HUGE_PAGE);
            if start > base {
                libc::munmap(p, start - base);
            }
            let tail = base + over - (start + len);
            if tail > 0 {
                libc::munmap((start + len) as *mut libc::c_void, tail);
            }
            libc::madvise(start as *mut libc::c_void, len, libc::MADV_HUGEPAGE);
            start as *mut u8
        }
    }

    /// Unmaps a mapping made by [`map`] for `size` bytes.
    ///
    /// # Safety
    /// `p` must come from `map(size)` and not be used afterwards.
    pub unsafe fn unmap(p: *mut u8, size: usize) {
        // SAFETY: the caller's contract: exactly the range `map` created.
        unsafe {
            libc::munmap(p as *mut libc::c_void, mapped_len(size));
        }
    }
}

impl HugePageAlloc {
    /// Whether an allocation of this layout gets a huge-page mapping.
    #[inline]
    fn large(layout: Layout) -> bool {
        #[cfg(target_os = "linux")]
        {
            layout.size() >= THRESHOLD && layout.align() <= HUGE_PAGE && imp::enabled()
        }
        #[cfg(not(target_os = "linux"))]
        {
            let _ = layout;
            false
        }
    }
}

// SAFETY: every block handed out is either the system allocator's (for layouts `large` rejects)
// or a private mapping of at least `layout.size()` bytes aligned to 2 MiB ≥ `layout.align()`;
// `large` depends only on the layout and on a setting read once, so `dealloc` and `realloc`
// route a block back to the allocator that made it.
unsafe impl GlobalAlloc for HugePageAlloc {
    #[inline]
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        #[cfg(target_os = "linux")]
        if Self::large(layout) {
            return imp::map(layout.size());
        }
        // SAFETY: forwarded with the caller's (non-zero-size) layout.
        unsafe { System.alloc(layout) }
    }

    #[inline]
    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        // A fresh anonymous mapping is already zero.
        #[cfg(target_os = "linux")]
        if Self::large(layout) {
            return imp::map(layout.size());
        }
        // SAFETY: as in `alloc`.
        unsafe { System.alloc_zeroed(layout) }
    }

    #[inline]
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        #[cfg(target_os = "linux")]
        if Self::large(layout) {
            // SAFETY: `ptr` came from `alloc` with this layout, hence from `map(layout.size())`.
            unsafe { imp::unmap(ptr, layout.size()) };
            return;
        }
        // SAFETY: `ptr` came from `System` with this layout.
        unsafe { System.dealloc(ptr, layout) }
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        // SAFETY: the caller guarantees `new_size` rounded to `layout.align()` fits `isize`.
        let new_layout = unsafe { Layout::from_size_align_unchecked(new_size, layout.align()) };
        let (old_large, new_large) = (Self::large(layout), Self::large(new_layout));
        if !old_large && !new_large {
            // SAFETY: a system block resized by the system allocator.
            return unsafe { System.realloc(ptr, layout, new_size) };
        }
        #[cfg(target_os = "linux")]
        if old_large && new_large && imp::mapped_len(layout.size()) == imp::mapped_len(new_size) {
            // Still fits the same mapping.
            return ptr;
        }
        // SAFETY: a new block from this allocator, the overlap copied, the old block freed by
        // the allocator that made it (the two blocks are distinct, so they do not overlap).
        unsafe {
            let new = self.alloc(new_layout);
            if !new.is_null() {
                std::ptr::copy_nonoverlapping(ptr, new, layout.size().min(new_size));
                self.dealloc(ptr, layout);
            }
            new
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Large blocks are 2 MiB-aligned, zeroed when asked, keep their bytes through growing,
    /// shrinking within and out of the huge-page range, and (where the kernel has transparent
    /// huge pages) carry the huge-page advice. Fails if the mapping is not aligned, `realloc`
    /// loses or shifts bytes, or `madvise` is not applied.
    #[test]
    fn large_blocks_are_aligned_advised_and_keep_their_bytes() {
        let a = HugePageAlloc;
        let size = 3 * HUGE_PAGE / 2 + 12_345;
        let layout = Layout::from_size_align(size, 16).unwrap();
        let pattern = |i: usize| (i.wrapping_mul(2_654_435_761) >> 7) as u8;
        unsafe {
            let p = a.alloc_zeroed(layout);
            assert!(!p.is_null());
            assert_eq!(p as usize % HUGE_PAGE, 0, "large blocks are 2 MiB-aligned");
            let s = std::slice::from_raw_parts_mut(p, size);
            assert!(s.iter().all(|&b| b == 0), "alloc_zeroed is zero");
            for (i, b) in s.iter_mut().enumerate() {
                *b = pattern(i);
            }
            #[cfg(target_os = "linux")]
            if std::path::Path::new("/sys/kernel/mm/transparent_hugepage/enabled").exists() {
                let smaps = std::fs::read_to_string("/proc/self/smaps").unwrap();
                let mut advised = None;
                let mut inside = false;
                for line in smaps.lines() {
                    let head = line.split_whitespace().next().unwrap_or("");
                    if let Some((lo, hi)) = head.split_once('-')
                        && let (Ok(lo), Ok(hi)) =
                            (usize::from_str_radix(lo, 16), usize::from_str_radix(hi, 16))
                    {
                        inside = lo <= p as usize && (p as usize) < hi;
                    } else if inside && let Some(flags) = line.strip_prefix("VmFlags:") {
                        advised = Some(flags.split_whitespace().any(|f| f == "hg"));
                    }
                }
                assert_eq!(advised, Some(true), "the mapping carries MADV_HUGEPAGE");
            }
            // Grow past the mapping: a new block with the same bytes.
            let big = 5 * HUGE_PAGE + 7;
            let q = a.realloc(p, layout, big);
            assert!(!q.is_null());
            assert_eq!(q as usize % HUGE_PAGE, 0);
            let s = std::slice::from_raw_parts_mut(q, big);
            assert!(
                (0..size).all(|i| s[i] == pattern(i)),
                "growing keeps the bytes"
            );
            // Shrink below the threshold: a system block with the prefix.
            let big_layout = Layout::from_size_align(big, 16).unwrap();
            let small = THRESHOLD / 3;
            let r = a.realloc(q, big_layout, small);
            assert!(!r.is_null());
            let s = std::slice::from_raw_parts(r, small);
            assert!(
                (0..small).all(|i| s[i] == pattern(i)),
                "shrinking keeps the prefix"
            );
            a.dealloc(r, Layout::from_size_align(small, 16).unwrap());
        }
    }

    /// Small blocks are the system allocator's and behave as such.
    #[test]
    fn small_blocks_round_trip() {
        let a = HugePageAlloc;
        let layout = Layout::from_size_align(100, 8).unwrap();
        unsafe {
            let p = a.alloc(layout);
            assert!(!p.is_null());
            std::ptr::write_bytes(p, 7, 100);
            let q = a.realloc(p, layout, 200);
            assert!((0..100).all(|i| *q.add(i) == 7));
            a.dealloc(q, Layout::from_size_align(200, 8).unwrap());
        }
    }
}
