//! The web UI's JSON API against a real `trayecto serve` process on 127.0.0.1 and an ephemeral
//! port: path traversal (plain, percent-encoded, absolute, symlinked), oversized bodies and
//! fields, absurd sizes, too many concurrent jobs, and cancel freeing its job. Requests are
//! written by hand on a TcpStream so nothing normalises the hostile paths before the server sees
//! them.

mod common;

use serde_json::{Value, json};
use std::io::{BufRead, BufReader, Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::atomic::{AtomicU32, Ordering};
use std::time::{Duration, Instant};

/// A server process, killed when dropped, with its own scenes and output folders.
struct Server {
    child: Child,
    addr: SocketAddr,
    root: PathBuf,
}

impl Drop for Server {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
        let _ = std::fs::remove_dir_all(&self.root);
    }
}

static COUNTER: AtomicU32 = AtomicU32::new(0);

/// A fresh temp folder with `scenes/` (a fake scene, a sub-folder, a non-scene file, a hidden file,
/// a symlink inside and one pointing outside) and `secret.gltf` beside it, outside the scenes.
fn fixture() -> PathBuf {
    let root = std::env::temp_dir().join(format!(
        "trayecto-serve-{}-{}",
        std::process::id(),
        COUNTER.fetch_add(1, Ordering::Relaxed)
    ));
    let _ = std::fs::remove_dir_all(&root);
    let scenes = root.join("scenes");
    std::fs::create_dir_all(scenes.join("sub")).unwrap();
    std::fs::write(scenes.join("fake.gltf"), b"{ this is not a real glTF file").unwrap();
    std::fs::write(scenes.join("sub/inner.obj"), b"# fake\n").unwrap();
    std::fs::write(scenes.join("notes.txt"), b"not a scene").unwrap();
    std::fs::write(scenes.join(".hidden.gltf"), b"{}").unwrap();
    std::fs::write(root.join("secret.gltf"), b"SECRET-CONTENT").unwrap();
    std::os::unix::fs::symlink(root.join("secret.gltf"), scenes.join("escape.gltf")).unwrap();
    std::os::unix::fs::symlink(scenes.join("fake.gltf"), scenes.join("alias.gltf")).unwrap();
    std::os::unix::fs::symlink(&root, scenes.join("loop")).unwrap();
    root
}

fn start_with(scenes: Option<&Path>, extra: &[&str]) -> Server {
    let root = fixture();
    let out = root.join("out");
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_trayecto"));
    cmd.args(["serve", "--port", "0", "--output"])
        .arg(&out)
        .args(["--threads", "1"])
        .args(extra)
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit());
    cmd.arg("--scenes");
    match scenes {
        Some(s) => cmd.arg(s),
        None => cmd.arg(root.join("scenes")),
    };
    let mut child = cmd.spawn().expect("start trayecto serve");
    let stdout = child.stdout.take().unwrap();
    let mut reader = BufReader::new(stdout);
    let mut line = String::new();
    reader.read_line(&mut line).unwrap();
    // Keep draining the rest of its output.
    std::thread::spawn(move || std::io::copy(&mut reader, &mut std::io::sink()));
    let addr = line
        .trim()
        .strip_prefix("trayecto serve: listening on http://")
        .and_then(|s| s.strip_suffix('/'))
        .unwrap_or_else(|| panic!("unexpected first line {line:?}"))
        .parse()
        .unwrap();
    Server { child, addr, root }
}

fn start() -> Server {
    start_with(None, &[])
}

struct Reply {
    status: u16,
    headers: Vec<(String, String)>,
    body: Vec<u8>,
}

impl Reply {
    fn json(&self) -> Value {
        serde_json::from_slice(&self.body).unwrap_or_else(|e| {
            panic!(
                "status {}: not JSON ({e}): {}",
                self.status,
                String::from_utf8_lossy(&self.body)
            )
        })
    }
    fn header(&self, name: &str) -> Option<&str> {
        self.headers
            .iter()
            .find(|(k, _)| k.eq_ignore_ascii_case(name))
            .map(|(_, v)| v.as_str())
    }
    fn text(&self) -> String {
        String::from_utf8_lossy(&self.body).into_owned()
    }
}

/// One HTTP/1.1 request with `Connection: close`; `head` is sent verbatim after the request line.
fn raw(s: &Server, request_line: &str, head: &str, body: &[u8]) -> Reply {
    let mut t = TcpStream::connect(s.addr).unwrap();
    t.set_read_timeout(Some(Duration::from_secs(30))).unwrap();
    let msg = format!(
        "{request_line} HTTP/1.1\r\nHost: {}\r\nConnection: close\r\n{head}\r\n",
        s.addr
    );
    t.write_all(msg.as_bytes()).unwrap();
    // The server may answer (and close) before reading a refused body: ignore write errors.
    let _ = t.write_all(body);
    let mut buf = Vec::new();
    let _ = t.read_to_end(&mut buf);
    parse_reply(&buf)
}

fn parse_reply(buf: &[u8]) -> Reply {
    let split = buf
        .windows(4)
        .position(|w| w == b"\r\n\r\n")
        .unwrap_or_else(|| panic!("no HTTP reply: {:?}", String::from_utf8_lossy(buf)));
    let head = String::from_utf8_lossy(&buf[..split]).into_owned();
    let mut lines = head.split("\r\n");
    let status: u16 = lines
        .next()
        .unwrap()
        .split(' ')
        .nth(1)
        .unwrap()
        .parse()
        .unwrap();
    let headers: Vec<(String, String)> = lines
        .filter_map(|l| l.split_once(':'))
        .map(|(k, v)| (k.trim().to_string(), v.trim().to_string()))
        .collect();
    let mut body = buf[split + 4..].to_vec();
    let chunked = headers
        .iter()
        .any(|(k, v)| k.eq_ignore_ascii_case("transfer-encoding") && v.contains("chunked"));
    if chunked {
        let mut out = Vec::new();
        let mut rest = &body[..];
        loop {
            let nl = rest.windows(2).position(|w| w == b"\r\n").unwrap();
            let n = usize::from_str_radix(std::str::from_utf8(&rest[..nl]).unwrap().trim(), 16)
                .unwrap();
            if n == 0 {
                break;
            }
            out.extend_from_slice(&rest[nl + 2..nl + 2 + n]);
            rest = &rest[nl + 2 + n + 2..];
        }
        body = out;
    }
    Reply {
        status,
        headers,
        body,
    }
}

fn get(s: &Server, path: &str) -> Reply {
    raw(s, &format!("GET {path}"), "", b"")
}

fn post_json(s: &Server, path: &str, body: &Value) -> Reply {
    let b = body.to_string();
    raw(
        s,
        &format!("POST {path}"),
        &format!(
            "Content-Type: application/json\r\nContent-Length: {}\r\n",
            b.len()
        ),
        b.as_bytes(),
    )
}

/// Polls a job until it is no longer active.
fn wait_finished(s: &Server, id: u64, timeout: Duration) -> Value {
    let t0 = Instant::now();
    loop {
        let j = get(s, &format!("/api/renders/{id}")).json();
        if j["active"] == false {
            return j;
        }
        assert!(t0.elapsed() < timeout, "job {id} still running: {j}");
        std::thread::sleep(Duration::from_millis(50));
    }
}

fn field_error(r: &Reply, field: &str) -> String {
    assert_eq!(r.status, 400, "{}", r.text());
    let j = r.json();
    j["fields"][field]
        .as_str()
        .unwrap_or_else(|| panic!("no message for '{field}' in {j}"))
        .to_string()
}

#[test]
fn page_assets_and_options_are_served() {
    let s = start();
    let page = get(&s, "/");
    assert_eq!(page.status, 200);
    assert!(page.text().contains("<form id=\"render-form\""));
    assert!(
        page.header("content-type")
            .unwrap()
            .starts_with("text/html")
    );
    assert!(page.header("content-security-policy").is_some());
    assert_eq!(get(&s, "/app.js").status, 200);
    assert_eq!(get(&s, "/style.css").status, 200);
    let o = get(&s, "/api/options").json();
    assert_eq!(o["limits"]["max_jobs"], 2);
    assert_eq!(o["limits"]["max_size"], 4096);
    assert!(
        o["integrators"]
            .as_array()
            .unwrap()
            .contains(&json!("path"))
    );
    assert_eq!(get(&s, "/no/such/page").status, 404);
}

#[test]
fn scene_listing_shows_only_scene_files_inside_the_folder() {
    let s = start();
    let l = get(&s, "/api/scenes").json();
    assert_eq!(l["builtin"], json!(["cornell"]));
    // No notes.txt (not a scene), no .hidden.gltf, no escape.gltf (symlink out), and the
    // symlinked folder `loop` (which points above the scenes folder) is not followed.
    assert_eq!(
        l["files"],
        json!(["alias.gltf", "fake.gltf", "sub/inner.obj"])
    );
}

#[test]
fn the_shared_scene_folder_is_listed() {
    let shared = common::shared_dir().join("scenes");
    let s = start_with(Some(&shared), &[]);
    let l = get(&s, "/api/scenes").json();
    let files: Vec<&str> = l["files"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_str().unwrap())
        .collect();
    assert!(
        files.contains(&"gltf/Box/glTF/Box.gltf"),
        "Box.gltf missing from {files:?}"
    );
    assert!(files.iter().any(|f| f.ends_with(".fbx")));
    assert!(
        files
            .iter()
            .all(|f| !f.starts_with('/') && !f.contains(".."))
    );
}

#[test]
fn path_traversal_is_refused() {
    let s = start();
    let secret = s.root.join("secret.gltf");
    let absolute = secret.to_string_lossy().into_owned();
    for name in [
        "../secret.gltf",
        "sub/../../secret.gltf",
        "..%2fsecret.gltf",
        "%2e%2e/secret.gltf",
        "..%252fsecret.gltf",
        "sub\\..\\..\\secret.gltf",
        "./fake.gltf",
        absolute.as_str(),
        "/etc/passwd",
        "escape.gltf",
        "loop/secret.gltf",
        "notes.txt",
        "missing.gltf",
        "sub",
        "fake.gltf\0",
        "",
    ] {
        let r = post_json(
            &s,
            "/api/renders",
            &json!({"scene": name, "output": "x", "width": 8, "height": 8, "spp": 1}),
        );
        let m = field_error(&r, "scene");
        assert!(!r.text().contains("SECRET-CONTENT"), "{name:?}: {m}");
    }
    // URLs never name files: encoded or not, traversal finds nothing.
    for path in [
        "/../secret.gltf",
        "/%2e%2e/secret.gltf",
        "/..%2f..%2f..%2fetc%2fpasswd",
        "/api/renders/1/..%2f..%2fsecret.gltf",
        "/api/renders/1/../../../etc/passwd",
        "/api/scenes/../../secret.gltf",
        "//etc/passwd",
    ] {
        let r = get(&s, path);
        assert!(r.status == 404 || r.status == 400, "{path}: {}", r.status);
        assert!(!r.text().contains("SECRET-CONTENT") && !r.text().contains("root:"));
    }
    // A file inside the folder (and a symlink that stays inside) is accepted; the fake content
    // then fails to load, reported on the job.
    for name in ["fake.gltf", "alias.gltf", "sub/inner.obj"] {
        let r = post_json(
            &s,
            "/api/renders",
            &json!({"scene": name, "output": "fake", "width": 8, "height": 8, "spp": 1}),
        );
        assert_eq!(r.status, 201, "{name}: {}", r.text());
        let j = wait_finished(
            &s,
            r.json()["id"].as_u64().unwrap(),
            Duration::from_secs(30),
        );
        assert_eq!(j["state"], "failed", "{j}");
        assert!(j["error"].as_str().unwrap().len() > 5);
    }
}

#[test]
fn output_names_are_plain_file_names() {
    let s = start();
    for name in [
        "../evil",
        "/tmp/evil",
        "a/b",
        "..",
        ".hidden",
        "evil\\x",
        "a b",
        "%2e%2e%2fevil",
    ] {
        let r = post_json(
            &s,
            "/api/renders",
            &json!({"scene": "cornell", "output": name, "width": 8, "height": 8, "spp": 1}),
        );
        field_error(&r, "output");
    }
    assert!(!s.root.join("evil.png").exists());
}

#[test]
fn a_small_render_completes_and_downloads() {
    let s = start();
    let r = post_json(
        &s,
        "/api/renders",
        &json!({"scene": "cornell", "output": "tiny.png", "width": 24, "height": 16, "spp": 4,
                "max_depth": 4}),
    );
    assert_eq!(r.status, 201, "{}", r.text());
    let id = r.json()["id"].as_u64().unwrap();
    let j = wait_finished(&s, id, Duration::from_secs(60));
    assert_eq!(j["state"], "done", "{j}");
    assert_eq!(j["samples_done"], 4);
    assert_eq!(j["progress"], 1.0);
    let phases: Vec<&str> = j["timings"]
        .as_array()
        .unwrap()
        .iter()
        .map(|t| t["phase"].as_str().unwrap())
        .collect();
    assert_eq!(
        phases,
        ["load", "build (accel)", "render", "write", "total"]
    );
    assert!(j["log"].as_array().unwrap().len() >= 3);

    let png = get(&s, j["png"].as_str().unwrap());
    assert_eq!(png.status, 200);
    assert_eq!(&png.body[..8], b"\x89PNG\r\n\x1a\n");
    let w = u32::from_be_bytes(png.body[16..20].try_into().unwrap());
    let h = u32::from_be_bytes(png.body[20..24].try_into().unwrap());
    assert_eq!((w, h), (24, 16));
    assert!(
        png.header("content-disposition")
            .unwrap()
            .contains("tiny.png")
    );
    let exr = get(&s, j["exr"].as_str().unwrap());
    assert_eq!(exr.status, 200);
    assert_eq!(&exr.body[..4], &[0x76, 0x2f, 0x31, 0x01]);
    // Written only inside the output folder, under the sanitised name.
    let mut files: Vec<String> = std::fs::read_dir(s.root.join("out"))
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    files.sort();
    assert_eq!(files, ["tiny.exr", "tiny.png"]);
    // The finished job is listed.
    let list = get(&s, "/api/renders").json();
    assert_eq!(list["renders"][0]["id"], id);
    assert_eq!(get(&s, "/api/renders/999").status, 404);
    assert_eq!(get(&s, "/api/renders/abc").status, 404);
    assert_eq!(get(&s, &format!("/api/renders/{id}/other.txt")).status, 404);
}

#[test]
fn oversized_and_absurd_requests_are_refused() {
    let s = start();
    // A body over the limit (16 KiB), sent in full.
    let big = json!({"scene": "cornell", "pad": "x".repeat(100_000)}).to_string();
    let r = raw(
        &s,
        "POST /api/renders",
        &format!(
            "Content-Type: application/json\r\nContent-Length: {}\r\n",
            big.len()
        ),
        big.as_bytes(),
    );
    assert_eq!(r.status, 413, "{}", r.text());
    // The same without a declared length (chunked): refused once it grows over the limit.
    let mut chunked = Vec::new();
    for part in big.as_bytes().chunks(8192) {
        chunked.extend_from_slice(format!("{:x}\r\n", part.len()).as_bytes());
        chunked.extend_from_slice(part);
        chunked.extend_from_slice(b"\r\n");
    }
    chunked.extend_from_slice(b"0\r\n\r\n");
    let r = raw(
        &s,
        "POST /api/renders",
        "Content-Type: application/json\r\nTransfer-Encoding: chunked\r\n",
        &chunked,
    );
    assert_eq!(r.status, 413, "{}", r.text());
    // An absurd declared length is refused from the header alone, without waiting for the body
    // (none is sent, so no unread bytes can turn the server's close into a reset).
    let t0 = Instant::now();
    let r = raw(
        &s,
        "POST /api/renders",
        "Content-Type: application/json\r\nContent-Length: 1000000000000000\r\n",
        b"",
    );
    assert_eq!(r.status, 413);
    assert!(t0.elapsed() < Duration::from_secs(5));
    // Over-long fields inside the limit.
    let r = post_json(
        &s,
        "/api/renders",
        &json!({"scene": "a".repeat(5000), "output": "b".repeat(300)}),
    );
    assert!(field_error(&r, "scene").contains("too long"));
    assert!(field_error(&r, "output").contains("too long"));
    // Absurd numbers, each named.
    let r = post_json(
        &s,
        "/api/renders",
        &json!({"scene": "cornell", "width": 1_000_000, "height": 0, "spp": 1_000_000_000u64,
                "secondary": 0, "max_depth": -1, "exposure": -2.0, "integrator": "magic",
                "seed": "x"}),
    );
    for f in [
        "width",
        "height",
        "spp",
        "secondary",
        "max_depth",
        "exposure",
        "integrator",
        "seed",
    ] {
        field_error(&r, f);
    }
    assert!(field_error(&r, "width").contains("1 to 4096"));
    // Within each cap but too much work together.
    let r = post_json(
        &s,
        "/api/renders",
        &json!({"scene": "cornell", "width": 4096, "height": 4096, "spp": 16384}),
    );
    assert!(field_error(&r, "spp").contains("budget"));
    // Not JSON, or not an object, or not declared as JSON.
    let r = raw(
        &s,
        "POST /api/renders",
        "Content-Type: application/json\r\nContent-Length: 5\r\n",
        b"{nope",
    );
    assert_eq!(r.status, 400);
    assert!(r.json()["error"].as_str().unwrap().contains("JSON"));
    assert_eq!(post_json(&s, "/api/renders", &json!([1, 2])).status, 400);
    let r = raw(
        &s,
        "POST /api/renders",
        "Content-Type: text/plain\r\nContent-Length: 18\r\n",
        br#"{"scene":"cornell"}"#,
    );
    assert_eq!(r.status, 415);
    // The server is still up.
    assert_eq!(get(&s, "/api/options").status, 200);
}

#[test]
fn foreign_hosts_and_origins_are_refused() {
    let s = start();
    // A page on another name that resolves to 127.0.0.1 (DNS rebinding) sends its own Host.
    let mut t = TcpStream::connect(s.addr).unwrap();
    t.write_all(
        b"GET /api/options HTTP/1.1\r\nHost: evil.example:8080\r\nConnection: close\r\n\r\n",
    )
    .unwrap();
    let mut buf = Vec::new();
    t.read_to_end(&mut buf).unwrap();
    assert_eq!(parse_reply(&buf).status, 403);
    let body = json!({"scene": "cornell", "width": 8, "height": 8, "spp": 1}).to_string();
    let r = raw(
        &s,
        "POST /api/renders",
        &format!(
            "Origin: http://evil.example\r\nContent-Type: application/json\r\nContent-Length: {}\r\n",
            body.len()
        ),
        body.as_bytes(),
    );
    assert_eq!(r.status, 403);
    assert_eq!(get(&s, "/api/renders").json()["renders"], json!([]));
}

#[test]
fn too_many_jobs_are_refused_and_cancel_frees_a_slot() {
    let s = start();
    // Long renders (they would take minutes): cancelled below.
    let long = |name: &str| {
        json!({"scene": "cornell", "output": name, "width": 256, "height": 256, "spp": 16384,
               "max_depth": 8})
    };
    let a = post_json(&s, "/api/renders", &long("a"));
    assert_eq!(a.status, 201, "{}", a.text());
    let a = a.json()["id"].as_u64().unwrap();
    // The same output name as a running job is refused.
    let dup = post_json(&s, "/api/renders", &long("a"));
    assert_eq!(dup.status, 409);
    let b = post_json(&s, "/api/renders", &long("b"));
    assert_eq!(b.status, 201);
    let b = b.json()["id"].as_u64().unwrap();
    let c = post_json(&s, "/api/renders", &long("c"));
    assert_eq!(c.status, 429, "{}", c.text());
    assert!(
        c.json()["error"]
            .as_str()
            .unwrap()
            .contains("already running")
    );

    // Wait for a preview of job a, then cancel it.
    let t0 = Instant::now();
    loop {
        let j = get(&s, &format!("/api/renders/{a}")).json();
        if j["preview_version"].as_u64().unwrap() > 0 {
            assert_eq!(j["state"], "rendering");
            let p = get(&s, j["preview"].as_str().unwrap());
            assert_eq!(p.status, 200);
            assert_eq!(&p.body[..8], b"\x89PNG\r\n\x1a\n");
            break;
        }
        assert!(t0.elapsed() < Duration::from_secs(30), "no preview: {j}");
        std::thread::sleep(Duration::from_millis(20));
    }
    let t_cancel = Instant::now();
    assert_eq!(
        raw(&s, &format!("POST /api/renders/{a}/cancel"), "", b"").status,
        200
    );
    let j = wait_finished(&s, a, Duration::from_secs(10));
    let latency = t_cancel.elapsed();
    eprintln!("cancel took {:.0} ms", latency.as_secs_f64() * 1e3);
    assert_eq!(j["state"], "cancelled");
    assert!(latency < Duration::from_secs(5), "cancel took {latency:?}");
    // Its preview (the image memory) is gone and no file was written.
    assert_eq!(
        get(&s, &format!("/api/renders/{a}/preview.png")).status,
        404
    );
    assert_eq!(j["png"], Value::Null);
    assert!(!s.root.join("out/a.png").exists());

    // The slot is free again.
    let c = post_json(&s, "/api/renders", &long("c"));
    assert_eq!(c.status, 201, "{}", c.text());
    let c = c.json()["id"].as_u64().unwrap();
    for id in [b, c] {
        raw(&s, &format!("POST /api/renders/{id}/cancel"), "", b"");
    }
    for id in [b, c] {
        assert_eq!(
            wait_finished(&s, id, Duration::from_secs(10))["state"],
            "cancelled"
        );
    }
    assert_eq!(get(&s, "/api/renders").json()["active"], 0);
}

/// Runs one render through the server and waits for it; returns (PNG bytes, EXR image).
fn server_render(s: &Server, body: &Value) -> (Vec<u8>, trayecto::film::Image) {
    let r = post_json(s, "/api/renders", body);
    assert_eq!(r.status, 201, "{body}: {}", r.text());
    let id = r.json()["id"].as_u64().unwrap();
    let j = wait_finished(s, id, Duration::from_secs(60));
    assert_eq!(j["state"], "done", "{j}");
    let png = get(s, j["png"].as_str().unwrap());
    assert_eq!(png.status, 200);
    let exr = get(s, j["exr"].as_str().unwrap());
    assert_eq!(exr.status, 200);
    let path = s.root.join(format!("fetched-{id}.exr"));
    std::fs::write(&path, &exr.body).unwrap();
    let img = trayecto::film::output::read_exr(&path).unwrap();
    (png.body, img)
}

/// The same render by the command line (whose options are tested in tests/cli.rs).
fn cli_render(dir: &Path, scene: &str, args: &[String]) -> (Vec<u8>, trayecto::film::Image) {
    let mut out = Vec::new();
    for ext in ["png", "exr"] {
        let file = dir.join(format!("cli.{ext}"));
        let o = Command::new(env!("CARGO_BIN_EXE_trayecto"))
            .args(["render", scene, "-q", "-o"])
            .arg(&file)
            .args(args)
            .output()
            .unwrap();
        assert!(
            o.status.success(),
            "{args:?}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
        out.push(file);
    }
    (
        std::fs::read(&out[0]).unwrap(),
        trayecto::film::output::read_exr(&out[1]).unwrap(),
    )
}

fn decode_png(bytes: &[u8]) -> Vec<u8> {
    image::load_from_memory(bytes).unwrap().to_rgb8().into_raw()
}

/// Every render field with a non-default value reaches the render and the image: the server's
/// PNG and EXR equal the command line's with the same settings (the image is a pure function of
/// the settings), and changing one field from the base request changes the EXR (integrator,
/// seed, secondary, max_depth) or only the PNG (exposure, tone map).
#[test]
fn every_render_field_reaches_the_image() {
    let s = start();
    let base = json!({"scene": "cornell", "width": 16, "height": 12, "spp": 2, "secondary": 1,
                      "max_depth": 16, "exposure": 1.0, "integrator": "path",
                      "tonemap": "clamp", "seed": 0});
    let args = |v: &Value| -> Vec<String> {
        let mut a = Vec::new();
        for (flag, key) in [
            ("--width", "width"),
            ("--height", "height"),
            ("--spp", "spp"),
            ("--secondary", "secondary"),
            ("--max-depth", "max_depth"),
            ("--exposure", "exposure"),
            ("--integrator", "integrator"),
            ("--tonemap", "tonemap"),
            ("--seed", "seed"),
        ] {
            a.push(flag.to_string());
            a.push(match &v[key] {
                Value::String(s) => s.clone(),
                other => other.to_string(),
            });
        }
        a
    };
    let variants: [(&str, Value, bool); 6] = [
        ("integrator", json!("whitted"), true),
        ("seed", json!(9), true),
        ("secondary", json!(3), true),
        ("max_depth", json!(1), true),
        ("exposure", json!(2.5), false),
        ("tonemap", json!("aces"), false),
    ];
    let mut body = base.clone();
    body["output"] = json!("base");
    let (base_png, base_exr) = server_render(&s, &body);
    let cli = cli_render(&s.root, "cornell", &args(&base));
    assert_eq!(
        base_exr, cli.1,
        "base request: server EXR differs from the CLI's"
    );
    assert_eq!(
        decode_png(&base_png),
        decode_png(&cli.0),
        "base request: PNG"
    );
    for (key, value, changes_radiance) in variants {
        let mut body = base.clone();
        body[key] = value.clone();
        let cli = cli_render(&s.root, "cornell", &args(&body));
        body["output"] = json!(format!("with-{key}"));
        let (png, exr) = server_render(&s, &body);
        assert_eq!(
            exr, cli.1,
            "{key} = {value}: server EXR differs from the CLI's"
        );
        assert_eq!(decode_png(&png), decode_png(&cli.0), "{key} = {value}: PNG");
        if changes_radiance {
            assert_ne!(exr, base_exr, "{key} = {value} did not change the render");
        } else {
            assert_eq!(exr, base_exr, "{key} = {value} changed the raw radiance");
            assert_ne!(
                decode_png(&png),
                decode_png(&base_png),
                "{key} = {value} did not change the PNG"
            );
        }
    }
}

/// A real scene file from `--scenes` renders, and gives the command line's image of that file.
#[test]
fn a_real_scene_file_from_the_scenes_folder_renders() {
    let dir = std::env::temp_dir().join(format!("trayecto-serve-real-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(dir.join("mitsuba")).unwrap();
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/mitsuba");
    for f in ["textured.toml", "checker.png"] {
        std::fs::copy(src.join(f), dir.join("mitsuba").join(f)).unwrap();
    }
    let s = start_with(Some(&dir), &[]);
    let files = get(&s, "/api/scenes").json()["files"].clone();
    assert_eq!(files, json!(["mitsuba/textured.toml"]));
    let (png, exr) = server_render(
        &s,
        &json!({"scene": "mitsuba/textured.toml", "output": "real", "width": 24, "height": 16,
                "spp": 2, "max_depth": 4, "seed": 3}),
    );
    let args: Vec<String> = [
        "--width",
        "24",
        "--height",
        "16",
        "--spp",
        "2",
        "--max-depth",
        "4",
        "--seed",
        "3",
    ]
    .iter()
    .map(|a| a.to_string())
    .collect();
    let cli = cli_render(
        &s.root,
        dir.join("mitsuba/textured.toml").to_str().unwrap(),
        &args,
    );
    assert_eq!(
        exr, cli.1,
        "the scene file renders differently through the server"
    );
    assert_eq!(decode_png(&png), decode_png(&cli.0));
    // Not black: the textured plane is lit.
    assert!(exr.mean().max_element() > 0.05, "{}", exr.mean());
    let _ = std::fs::remove_dir_all(&dir);
}

/// Old jobs are evicted: each submission forgets the finished jobs beyond the 10 newest (the
/// history), oldest first, and keeps the one it adds. After 12 jobs run one after another, the
/// list is jobs 2–12 (10 finished at the last submission + that one), and job 1 is gone.
#[test]
fn old_jobs_are_evicted() {
    let s = start();
    let mut ids = Vec::new();
    for i in 0..12 {
        let r = post_json(
            &s,
            "/api/renders",
            &json!({"scene": "cornell", "output": format!("job{i}"), "width": 8, "height": 8,
                    "spp": 1, "max_depth": 2}),
        );
        assert_eq!(r.status, 201, "{}", r.text());
        let id = r.json()["id"].as_u64().unwrap();
        assert_eq!(
            wait_finished(&s, id, Duration::from_secs(30))["state"],
            "done"
        );
        ids.push(id);
        let listed = get(&s, "/api/renders").json()["renders"]
            .as_array()
            .unwrap()
            .len();
        assert_eq!(listed, (i + 1).min(11), "after job {i}");
    }
    let listed: Vec<u64> = get(&s, "/api/renders").json()["renders"]
        .as_array()
        .unwrap()
        .iter()
        .map(|j| j["id"].as_u64().unwrap())
        .collect();
    let newest: Vec<u64> = ids[1..].iter().rev().copied().collect();
    assert_eq!(listed, newest, "the newest, newest first");
    assert_eq!(get(&s, &format!("/api/renders/{}", ids[0])).status, 404);
    assert_eq!(get(&s, &format!("/api/renders/{}", ids[1])).status, 200);
}

/// Unknown fields (a typo would otherwise silently fall back to a default) are refused, named.
#[test]
fn unknown_fields_are_refused() {
    let s = start();
    for (field, body) in [
        ("max-depth", json!({"scene": "cornell", "max-depth": 3})),
        ("samples", json!({"scene": "cornell", "samples": 3})),
        ("Width", json!({"scene": "cornell", "Width": 3})),
    ] {
        let r = post_json(&s, "/api/renders", &body);
        assert_eq!(r.status, 400, "{body}: {}", r.text());
        assert!(r.text().contains(field), "{body}: {}", r.text());
    }
    assert_eq!(get(&s, "/api/renders").json()["renders"], json!([]));
}

/// An output name that an earlier, finished render wrote is refused (409), not silently
/// overwritten: its files stay as they were.
#[test]
fn reusing_a_finished_output_name_is_refused() {
    let s = start();
    let body = json!({"scene": "cornell", "output": "same", "width": 8, "height": 8, "spp": 1,
                      "seed": 1});
    let (png, _) = server_render(&s, &body);
    let mut again = body.clone();
    again["seed"] = json!(2);
    let r = post_json(&s, "/api/renders", &again);
    assert_eq!(r.status, 409, "{}", r.text());
    assert!(r.text().contains("same"), "{}", r.text());
    assert_eq!(std::fs::read(s.root.join("out/same.png")).unwrap(), png);
    // A name used by nothing yet is accepted.
    again["output"] = json!("other");
    assert_eq!(post_json(&s, "/api/renders", &again).status, 201);
}
