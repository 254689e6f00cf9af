//! Partial films (`.trp`) from hostile hands: a header's claims are checked against the file's
//! size and the pixel data against the header before the arrays are allocated (a forged film
//! costs the time to unpack it, never the memory it asks for), and merged counts saturate
//! instead of wrapping round. Memory is measured by this test binary's own allocator.

use std::alloc::{GlobalAlloc, Layout, System};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::sync::atomic::{AtomicUsize, Ordering};
use trayecto::film::Film;
use trayecto::split::partial::{Part, PartFile, PartHeader, merge};

/// The system allocator, counting the bytes live and the peak since the last reset.
struct Counting;
static LIVE: AtomicUsize = AtomicUsize::new(0);
static PEAK: AtomicUsize = AtomicUsize::new(0);

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, l: Layout) -> *mut u8 {
        let p = unsafe { System.alloc(l) };
        if !p.is_null() {
            let now = LIVE.fetch_add(l.size(), Ordering::Relaxed) + l.size();
            PEAK.fetch_max(now, Ordering::Relaxed);
        }
        p
    }
    unsafe fn dealloc(&self, p: *mut u8, l: Layout) {
        unsafe { System.dealloc(p, l) };
        LIVE.fetch_sub(l.size(), Ordering::Relaxed);
    }
}

#[global_allocator]
static ALLOC: Counting = Counting;

/// Tests measuring the peak run one at a time.
static SERIAL: Mutex<()> = Mutex::new(());

fn dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("trayecto-partial-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// A real header of a tiny frame (the library's own), resized to `side`².
fn header(side: u32, discarded: u64) -> PartHeader {
    let frame = trayecto::split::FrameId {
        scene: "cornell".into(),
        digest: "0".repeat(64),
        settings: trayecto::render::RenderSettings {
            width: side,
            height: side,
            spp: 4,
            ..Default::default()
        },
        world: Default::default(),
        light_sampler: trayecto::light::LightSamplerKind::Power,
    };
    frame.header([0, 2], discarded)
}

/// Writes a `.trp` of `header` whose pixel data is `bytes` zero bytes, zlib-compressed.
fn zeros_file(path: &Path, h: &PartHeader, bytes: usize) {
    let json = serde_json::to_vec(h).unwrap();
    let mut f = Vec::new();
    f.extend_from_slice(b"TRAYPART");
    f.extend_from_slice(&(json.len() as u32).to_le_bytes());
    f.extend_from_slice(&json);
    let mut z = flate2::write::ZlibEncoder::new(f, flate2::Compression::best());
    let zeros = vec![0u8; 1 << 20];
    let mut left = bytes;
    while left > 0 {
        let k = left.min(zeros.len());
        z.write_all(&zeros[..k]).unwrap();
        left -= k;
    }
    std::fs::write(path, z.finish().unwrap()).unwrap();
}

/// Zeros claiming 2048² pixels (218 MB of sums and counts once unpacked, a 0.2 MB file): every
/// count is 0 although the header says no sample was discarded, which the first pass finds
/// while holding a few buffers, not the 200 MB of arrays.
#[test]
fn forged_zeros_are_refused_before_the_arrays_are_allocated() {
    let _one = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    let d = dir("zeros");
    let side = 2048u32;
    let path = d.join("zeros.trp");
    zeros_file(&path, &header(side, 0), side as usize * side as usize * 52);
    let base = LIVE.load(Ordering::Relaxed);
    PEAK.store(base, Ordering::Relaxed);
    let e = Part::read(&path).unwrap_err().to_string();
    let peak = PEAK.load(Ordering::Relaxed) - base;
    assert!(
        e.contains("zeros.trp") && e.contains("discarded") && e.contains("does not belong"),
        "{e}"
    );
    assert!(
        peak < 16 << 20,
        "reading the forged film allocated {peak} bytes at its peak"
    );
    let _ = std::fs::remove_dir_all(&d);
}

/// A header claiming more pixels than the rest of the file could hold even at deflate's best
/// ratio is refused from the header and the file size alone.
#[test]
fn a_header_claiming_more_than_the_file_holds_is_refused_from_its_size() {
    let _one = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    let d = dir("claim");
    let path = d.join("claim.trp");
    // 8192² pixels (3.5 GB unpacked) from 1 MB of zeros.
    zeros_file(&path, &header(8192, 0), 1 << 20);
    let e = PartFile::open(&path).err().expect("refused").to_string();
    assert!(
        e.contains("claim.trp") && e.contains("8192x8192") && e.contains("more than"),
        "{e}"
    );
    let _ = std::fs::remove_dir_all(&d);
}

/// A real film still reads back exactly, discarded samples included.
#[test]
fn a_genuine_film_with_discarded_samples_reads_back() {
    let d = dir("genuine");
    let (w, h) = (5u32, 3u32);
    let n = (w * h) as usize;
    // Samples 0..2 of every pixel, one of pixel 4's discarded.
    let mut count = vec![2u32; n];
    count[4] = 1;
    let sum = vec![[1i128 << 60, 0, -(1i128 << 59)]; n];
    let film = Film::from_raw(w, h, sum, count, 1).unwrap();
    let mut hd = header(0, 1);
    hd.width = w;
    hd.height = h;
    let part = Part { header: hd, film };
    let path = d.join("g.trp");
    part.write(&path).unwrap();
    let back = Part::read(&path).unwrap();
    assert_eq!(back.film, part.film);
    assert_eq!(back.header, part.header);
    // The same pixels under a header that says nothing was discarded: refused.
    let mut lying = part.clone();
    lying.header.discarded = 0;
    lying.film.discarded = 0;
    lying.write(&path).unwrap();
    let e = Part::read(&path).unwrap_err().to_string();
    assert!(e.contains("lack 1 of their 30 samples"), "{e}");
    let _ = std::fs::remove_dir_all(&d);
}

/// Two parts whose discarded counts are 2⁶³ each merge to a saturated count, not 0.
#[test]
fn merged_discarded_counts_saturate() {
    let part = |samples: [u32; 2]| {
        let mut h = header(0, 1 << 63);
        h.width = 2;
        h.height = 1;
        h.samples = samples;
        let film = Film::from_raw(2, 1, vec![[0; 3]; 2], vec![0; 2], 1 << 63).unwrap();
        Part { header: h, film }
    };
    let merged = merge(
        vec![
            (PathBuf::from("a.trp"), part([0, 2])),
            (PathBuf::from("b.trp"), part([2, 4])),
        ],
        true,
    )
    .unwrap();
    assert_eq!(merged.header.discarded, u64::MAX);
    assert_eq!(merged.film.discarded, u64::MAX);
}
