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
//! here are their own 2 MiB-aligned mappings whose length is a multiple of 2 MiB. Blocks start
//! at staggered offsets into their mappings (up to 128 KiB, a different cache set each), so that
//! equally sized arrays read at the same index do not all compete for one cache set.
//!
//! It changes where bytes live, never what they are: images are bit-identical. Small
//! allocations (below [`THRESHOLD`]) go to the system allocator unchanged. An allocation of
//! `n ≥ THRESHOLD` bytes maps `n` plus its offset (≤ 128 KiB) rounded up to 2 MiB: on average
//! about 1 MiB more per large allocation (untouched tail pages are never resident with 4 KiB
//! pages, but a touched huge page is all resident), and a render has a few dozen. `TRAYECTO_HUGEPAGES=0` in the
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
    use std::sync::atomic::{AtomicU8, AtomicUsize, Ordering};

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

    /// Allocations made so far, for [`colour`].
    static COUNT: AtomicUsize = AtomicUsize::new(0);

    /// Where the next block starts inside its mapping: the `k`-th large block is offset by
    /// `(65 k mod 2048)` cache lines (up to 128 KiB), so blocks do not all start at the same
    /// cache set. Without it every block would start 2 MiB-aligned, and the same texel of
    /// several equally sized textures (one uv, looked up in the base colour, normal, ORM, …
    /// maps) would fall in one set of every cache level: callgrind counted ToyCar's L1 data
    /// misses up 17 % (1.78 M → 2.08 M) with aligned starts. 65 is odd, so consecutive
    /// blocks get distinct sets in any cache of up to 2048 sets per way.
    fn colour() -> usize {
        let k = COUNT.fetch_add(1, Ordering::Relaxed);
        (k.wrapping_mul(65) % 2048) * 64
    }

    /// The mapping length for a block of `size` bytes at offset `offset` into its mapping.
    pub fn mapped_len(offset: usize, size: usize) -> usize {
        (offset + size).div_ceil(HUGE_PAGE) * HUGE_PAGE
    }

    /// The offset of block `p` into its mapping (mappings are `HUGE_PAGE`-aligned and offsets
    /// below `HUGE_PAGE`).
    pub fn offset_of(p: *mut u8) -> usize {
        p as usize % HUGE_PAGE
    }

    /// A zeroed block of `size` bytes in a fresh, `HUGE_PAGE`-aligned read-write mapping
    /// advised for huge pages, starting [`colour`] bytes into it rounded up to `align` (at most
    /// `HUGE_PAGE`), or null.
    pub fn map(size: usize, align: usize) -> *mut u8 {
        let offset = colour().next_multiple_of(align) % HUGE_PAGE;
        let Some(len) = size
            .checked_add(offset + 2 * HUGE_PAGE)
            .map(|_| mapped_len(offset, size))
        else {
            return std::ptr::null_mut();
        };
        let over = len + HUGE_PAGE;
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
            (start + offset) as *mut u8
        }
    }

    /// Unmaps the mapping of block `p` of `size` bytes made by [`map`].
    ///
    /// # Safety
    /// `p` must come from `map(size, _)` and not be used afterwards.
    pub unsafe fn unmap(p: *mut u8, size: usize) {
        let offset = offset_of(p);
        // SAFETY: the caller's contract: exactly the range `map` created.
        unsafe {
            libc::munmap(p.sub(offset) as *mut libc::c_void, mapped_len(offset, size));
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
// or a block of at least `layout.size()` bytes in a private mapping, aligned to
// `layout.align()` ≤ 2 MiB;
// `large` depends only on the layout and on a setting read once, so `dealloc` and `realloc`
// route a block back to the allocator that made it.
unsafe impl GlobalAlloc for HugePageAlloc {
    #[inline]
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        #[cfg(target_os = "linux")]
        if Self::large(layout) {
            return imp::map(layout.size(), layout.align());
        }
        // SAFETY: forwarded with the caller's (non-zero-size) layout.
        unsafe { System.alloc(layout) }
    }

    #[inline]
    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        // A fresh anonymous mapping is already zero.
        #[cfg(target_os = "linux")]
        if Self::large(layout) {
            return imp::map(layout.size(), layout.align());
        }
        // SAFETY: as in `alloc`.
        unsafe { System.alloc_zeroed(layout) }
    }

    #[inline]
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        #[cfg(target_os = "linux")]
        if Self::large(layout) {
            // SAFETY: `ptr` came from `alloc` with this layout, hence from `map(layout.size(), _)`.
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
        if old_large && new_large && {
            let offset = imp::offset_of(ptr);
            imp::mapped_len(offset, layout.size()) == imp::mapped_len(offset, new_size)
        } {
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

    /// The mapping in /proc/self/smaps holding address `p`: its start, end and whether it
    /// carries the huge-page advice (`hg` in VmFlags).
    #[cfg(target_os = "linux")]
    fn mapping_of(p: usize) -> Option<(usize, usize, bool)> {
        let smaps = std::fs::read_to_string("/proc/self/smaps").unwrap();
        let mut found = None;
        for line in smaps.lines() {
            let head = line.split_whitespace().next().unwrap_or("");
            if let Some((lo, hi)) = head.split_once('-')
                && let (Ok(lo), Ok(hi)) =
                    (usize::from_str_radix(lo, 16), usize::from_str_radix(hi, 16))
            {
                if found.is_some() {
                    break;
                }
                if lo <= p && p < hi {
                    found = Some((lo, hi, false));
                }
            } else if let Some((_, _, hg)) = found.as_mut()
                && let Some(flags) = line.strip_prefix("VmFlags:")
            {
                *hg = flags.split_whitespace().any(|f| f == "hg");
            }
        }
        found
    }

    /// Large blocks lie in 2 MiB-aligned mappings advised for huge pages (where the kernel has
    /// transparent huge pages), start at different cache sets, are zeroed when asked and keep
    /// their bytes through growing and shrinking within and out of the huge-page range. Fails
    /// if the mapping is not aligned or not advised, blocks all start at one offset, or
    /// `realloc` loses or shifts bytes (and with `TRAYECTO_HUGEPAGES=0`, checked).
    #[test]
    fn large_blocks_are_advised_coloured_and_keep_their_bytes() {
        let a = HugePageAlloc;
        let size = 3 * HUGE_PAGE / 2 + 12_345;
        let layout = Layout::from_size_align(size, 16).unwrap();
        let pattern = |i: usize| (i.wrapping_mul(2_654_435_761) >> 7) as u8;
        unsafe {
            let p = a.alloc_zeroed(layout);
            let other = a.alloc(layout);
            assert!(!p.is_null() && !other.is_null());
            assert_eq!(p as usize % 64, 0);
            assert_ne!(
                p as usize % 16384,
                other as usize % 16384,
                "consecutive blocks start in different cache sets"
            );
            let s = std::slice::from_raw_parts_mut(p, size);
            assert!(s.iter().all(|&b| b == 0), "alloc_zeroed is zero");
            for (i, b) in s.iter_mut().enumerate() {
                *b = pattern(i);
            }
            #[cfg(target_os = "linux")]
            if std::path::Path::new("/sys/kernel/mm/transparent_hugepage/enabled").exists() {
                let (lo, hi, hg) = mapping_of(p as usize).expect("the block is mapped");
                assert_eq!(lo % HUGE_PAGE, 0, "the mapping is 2 MiB-aligned");
                assert!(hi >= p as usize + size && (hi - lo) % HUGE_PAGE == 0);
                assert!(hg, "the mapping carries MADV_HUGEPAGE");
            }
            a.dealloc(other, layout);
            // Grow past the mapping: a new block with the same bytes.
            let big = 5 * HUGE_PAGE + 7;
            let q = a.realloc(p, layout, big);
            assert!(!q.is_null());
            let s = std::slice::from_raw_parts_mut(q, big);
            assert!(
                (0..size).all(|i| s[i] == pattern(i)),
                "growing keeps the bytes"
            );
            // Shrink within the mapping (in place), then below the threshold: a system block
            // with the prefix.
            let big_layout = Layout::from_size_align(big, 16).unwrap();
            let mid = 5 * HUGE_PAGE - HUGE_PAGE / 2;
            let q2 = a.realloc(q, big_layout, mid);
            assert!((0..size).all(|i| *q2.add(i) == pattern(i)));
            let small = THRESHOLD / 3;
            let r = a.realloc(q2, Layout::from_size_align(mid, 16).unwrap(), small);
            assert!(!r.is_null());
            let s = std::slice::from_raw_parts(r, small);
            assert!(
                (0..small).all(|i| s[i] == pattern(i)),
                "shrinking keeps the prefix"
            );
            a.dealloc(r, Layout::from_size_align(small, 16).unwrap());
            // A block aligned beyond the colour step keeps its alignment.
            let wide = Layout::from_size_align(THRESHOLD, 4096).unwrap();
            let w = a.alloc(wide);
            assert!(!w.is_null() && (w as usize).is_multiple_of(4096));
            a.dealloc(w, wide);
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
