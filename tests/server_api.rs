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
    /// The access token the server printed, if any.
    token: Option<String>,
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
    start_env(scenes, extra, &[])
}

fn start_env(scenes: Option<&Path>, extra: &[&str], env: &[(&str, &str)]) -> Server {
    let root = fixture();
    let out = root.join("out");
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_trayecto"));
    cmd.args(["serve", "--port", "0", "--output"])
        .arg(&out)
        .args(["--threads", "1"])
        .args(extra)
        .envs(env.iter().copied())
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
    // The banner ends with the output folder; a token line comes before it.
    let mut token = None;
    loop {
        let mut l = String::new();
        if reader.read_line(&mut l).unwrap() == 0 || l.starts_with("output:") {
            break;
        }
        if let Some((_, t)) = l.trim().split_once("?token=") {
            token = Some(t.to_string());
        }
    }
    // Keep draining the rest of its output.
    std::thread::spawn(move || std::io::copy(&mut reader, &mut std::io::sink()));
    let addr = line
        .trim()
        .strip_prefix("trayecto serve: listening on http://")
        .and_then(|s| s.strip_suffix('/'))
        .unwrap_or_else(|| panic!("unexpected first line {line:?}"))
        .parse()
        .unwrap();
    Server {
        child,
        addr,
        root,
        token,
    }
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

/// GETs `path` (a `/linear` endpoint), requires 200 and decodes its little-endian f32 body.
fn get_floats(s: &Server, path: &str) -> Vec<f32> {
    let r = get(s, path);
    assert_eq!(r.status, 200, "{path}");
    r.body
        .chunks_exact(4)
        .map(|b| f32::from_le_bytes(b.try_into().unwrap()))
        .collect()
}

/// The job that writes `output`, as `GET /api/renders` lists it.
fn listed_job(s: &Server, output: &str) -> Value {
    let list = get(s, "/api/renders").json();
    list["renders"]
        .as_array()
        .unwrap()
        .iter()
        .find(|j| j["output"] == output)
        .unwrap_or_else(|| panic!("no job writes '{output}': {list}"))
        .clone()
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
    // Without a queue, a render beyond --max-jobs is refused.
    let s = start_with(None, &["--max-queue", "0"]);
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
            .contains("the queue is full (2 renders running, 0 waiting)")
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
fn cli_render<A: AsRef<std::ffi::OsStr> + std::fmt::Debug>(
    dir: &Path,
    scene: &str,
    args: &[A],
) -> (Vec<u8>, trayecto::film::Image) {
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
    let args = [
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
    ];
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

/// `"denoise": true`: with Open Image Denoise installed the job also writes and serves
/// the denoised image; without it the job fails before rendering, naming the install command; a
/// non-boolean value is refused, named.
#[test]
fn denoise_field_serves_the_denoised_image_or_names_the_install_command() {
    let s = start_env(
        None,
        &[],
        &[("TRAYECTO_OIDN", "/nonexistent/libOpenImageDenoise.so")],
    );
    let r = post_json(
        &s,
        "/api/renders",
        &json!({"scene": "cornell", "denoise": "yes"}),
    );
    assert_eq!(r.status, 400, "{}", r.text());
    assert!(field_error(&r, "denoise").contains("true or false"));
    let body = json!({"scene": "cornell", "output": "dn", "width": 16, "height": 16, "spp": 2,
                      "denoise": true});
    let r = post_json(&s, "/api/renders", &body);
    assert_eq!(r.status, 201, "{}", r.text());
    let j = wait_finished(
        &s,
        r.json()["id"].as_u64().unwrap(),
        Duration::from_secs(60),
    );
    assert_eq!(j["state"], "failed", "{j}");
    let error = j["error"].as_str().unwrap();
    assert!(error.contains("./scripts/install-oidn.sh"), "{error}");
    assert!(!s.root.join("out/dn.png").exists());

    // scripts/test.sh installs Open Image Denoise before the tests: its absence is a failure.
    if let Err(e) = trayecto::denoise::Oidn::load(None) {
        panic!("Open Image Denoise is not installed ({e}): run ./scripts/install-oidn.sh");
    }
    let s = start();
    let r = post_json(&s, "/api/renders", &body);
    assert_eq!(r.status, 201, "{}", r.text());
    let j = wait_finished(
        &s,
        r.json()["id"].as_u64().unwrap(),
        Duration::from_secs(120),
    );
    assert_eq!(j["state"], "done", "{j}");
    assert_eq!(j["denoise"], true);
    let raw = get(&s, j["png"].as_str().unwrap());
    let denoised = get(&s, j["denoised_png"].as_str().unwrap());
    assert_eq!(denoised.status, 200);
    assert_eq!(denoised.header("content-type"), Some("image/png"));
    assert_ne!(denoised.body, raw.body);
    assert_eq!(get(&s, j["denoised_exr"].as_str().unwrap()).status, 200);
    assert!(s.root.join("out/dn.denoised.exr").is_file());
    // The denoised image is the command line's `--denoise` output of the same render, bit for bit
    // (the denoiser runs on the CPU with the same inputs, albedo and normal guides).
    let o = Command::new(env!("CARGO_BIN_EXE_trayecto"))
        .args([
            "render", "cornell", "-q", "--width", "16", "--height", "16", "--spp", "2",
        ])
        .args(["--denoise", "-o"])
        .arg(s.root.join("cli.exr"))
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let cli = trayecto::film::output::read_exr(&s.root.join("cli.denoised.exr")).unwrap();
    let server = trayecto::film::output::read_exr(&s.root.join("out/dn.denoised.exr")).unwrap();
    assert!(
        cli == server,
        "the server's denoised image differs from the CLI's --denoise"
    );
}

/// GET with extra header lines.
fn get_with(s: &Server, path: &str, head: &str) -> Reply {
    raw(s, &format!("GET {path}"), head, b"")
}

#[test]
fn a_non_loopback_address_requires_the_token() {
    // 127.0.0.2 stands for a public address: only 127.0.0.1 and ::1 are served without a token.
    let s = start_with(None, &["--host", "127.0.0.2"]);
    assert_eq!(s.addr.ip().to_string(), "127.0.0.2");
    let token = s.token.clone().expect("a generated token is printed");
    assert_eq!(token.len(), 32, "{token}");
    for path in ["/api/options", "/api/renders", "/", "/app.js"] {
        let r = get(&s, path);
        assert_eq!(r.status, 401, "{path}: {}", r.text());
        assert!(r.text().contains("access token"), "{}", r.text());
    }
    // A POST without the token starts nothing.
    let r = post_json(
        &s,
        "/api/renders",
        &json!({"scene": "cornell", "width": 8, "height": 8}),
    );
    assert_eq!(r.status, 401);
    let bearer = format!("Authorization: Bearer {token}\r\n");
    assert_eq!(
        get_with(&s, "/api/renders", &bearer).json()["renders"],
        json!([])
    );
    // A wrong token, in every place, is refused.
    // The token with its last digit changed (a fixed "0" equalled the token one time in 16).
    let last = if token.ends_with('0') { '1' } else { '0' };
    let wrong = format!("{}{last}", &token[..31]);
    assert_ne!(wrong, token);
    assert_eq!(
        get_with(
            &s,
            "/api/options",
            &format!("Authorization: Bearer {wrong}\r\n")
        )
        .status,
        401
    );
    assert_eq!(get(&s, &format!("/?token={wrong}")).status, 401);
    // The printed address sets the cookie and drops the token from the address.
    let r = get(&s, &format!("/?token={token}"));
    assert_eq!(r.status, 303);
    assert_eq!(r.header("location"), Some("/"));
    let cookie = r.header("set-cookie").unwrap().to_string();
    assert!(
        cookie.contains("HttpOnly") && cookie.contains("SameSite=Strict"),
        "{cookie}"
    );
    let pair = cookie.split(';').next().unwrap();
    let with_cookie = format!("Cookie: other=1; {pair}\r\n");
    assert_eq!(get_with(&s, "/", &with_cookie).status, 200);
    assert_eq!(get_with(&s, "/api/options", &with_cookie).status, 200);
    // A cookie with the wrong value is not enough.
    let bad_cookie = format!("Cookie: {}={wrong}\r\n", pair.split('=').next().unwrap());
    assert_eq!(get_with(&s, "/api/options", &bad_cookie).status, 401);
}

#[test]
fn serving_without_a_token_is_refused_off_loopback() {
    let run = |args: &[&str]| {
        Command::new(env!("CARGO_BIN_EXE_trayecto"))
            .args(["serve", "--port", "0"])
            .args(args)
            .output()
            .unwrap()
    };
    let o = run(&["--host", "127.0.0.2", "--no-token"]);
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("refusing to serve on 127.0.0.2 without a token"),
        "{err}"
    );
    let o = run(&["--host", "127.0.0.2", "--token", "short"]);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("--token must be 16 to 256"));
    // A token given on loopback is required there too.
    let s = start_with(None, &["--token", "0123456789abcdef-given"]);
    assert_eq!(s.token.as_deref(), Some("0123456789abcdef-given"));
    assert_eq!(get(&s, "/api/options").status, 401);
    let h = "X-Trayecto-Token: 0123456789abcdef-given\r\n";
    assert_eq!(get_with(&s, "/api/options", h).status, 200);
}

/// The state of every job, by output name.
fn states(s: &Server) -> Vec<(String, String)> {
    let l = get(s, "/api/renders").json();
    l["renders"]
        .as_array()
        .unwrap()
        .iter()
        .map(|j| {
            (
                j["output"].as_str().unwrap().to_string(),
                j["state"].as_str().unwrap().to_string(),
            )
        })
        .collect()
}

#[test]
fn renders_beyond_max_jobs_queue_and_complete_in_order() {
    let s = start_with(None, &["--max-jobs", "1", "--max-queue", "3"]);
    let job = |name: &str, spp: u32| {
        let r = post_json(
            &s,
            "/api/renders",
            &json!({"scene": "cornell", "output": name, "width": 48, "height": 48, "spp": spp,
                    "max_depth": 4}),
        );
        assert_eq!(r.status, 201, "{}", r.text());
        r.json()
    };
    let first = job("q1", 2048);
    let second = job("q2", 16);
    let third = job("q3", 16);
    let doomed = job("q4", 16);
    assert_eq!(second["state"], "queued");
    assert_eq!(second["queue_position"], 1);
    assert_eq!(third["queue_position"], 2);
    assert_eq!(doomed["queue_position"], 3);
    // The queue is full.
    let r = post_json(
        &s,
        "/api/renders",
        &json!({"scene": "cornell", "output": "q5"}),
    );
    assert_eq!(r.status, 429, "{}", r.text());
    // Cancelling a queued job ends it at once; the ones behind it move up.
    let id = |j: &Value| j["id"].as_u64().unwrap();
    let c = raw(
        &s,
        &format!("POST /api/renders/{}/cancel", id(&doomed)),
        "",
        b"",
    );
    assert_eq!(c.json()["state"], "cancelled");
    assert_eq!(c.json()["queue_position"], Value::Null);
    // Completion order, watched: never two rendering at once.
    let mut done_order = Vec::new();
    let t0 = Instant::now();
    while done_order.len() < 3 {
        let st = states(&s);
        let busy = st
            .iter()
            .filter(|(_, s)| !["queued", "done", "cancelled"].contains(&s.as_str()))
            .count();
        assert!(busy <= 1, "{st:?}");
        for (name, state) in st {
            if state == "done" && !done_order.contains(&name) {
                done_order.push(name);
            }
        }
        assert!(t0.elapsed() < Duration::from_secs(120), "{:?}", states(&s));
        std::thread::sleep(Duration::from_millis(10));
    }
    assert_eq!(done_order, ["q1", "q2", "q3"]);
    let _ = first;
    assert!(!s.root.join("out/q4.png").exists());
    let d = wait_finished(&s, id(&doomed), Duration::from_secs(1));
    assert_eq!(d["png"], Value::Null);
}

fn upload(s: &Server, name: &str, body: &[u8], content_type: &str) -> Reply {
    raw(
        s,
        &format!("POST /api/uploads?name={name}"),
        &format!(
            "Content-Type: {content_type}\r\nContent-Length: {}\r\n",
            body.len()
        ),
        body,
    )
}

#[test]
fn an_uploaded_model_is_listed_and_renders() {
    let s = start();
    let glb =
        std::fs::read(common::shared_dir().join("scenes/gltf/Box/glTF-Binary/Box.glb")).unwrap();
    let r = upload(&s, "box.glb", &glb, "application/octet-stream");
    assert_eq!(r.status, 201, "{}", r.text());
    assert_eq!(r.json()["scenes"], json!(["uploads/box.glb"]));
    let files = get(&s, "/api/scenes").json()["files"].clone();
    assert!(
        files
            .as_array()
            .unwrap()
            .contains(&json!("uploads/box.glb")),
        "{files}"
    );
    let r = post_json(
        &s,
        "/api/renders",
        &json!({"scene": "uploads/box.glb", "output": "box",
        "width": 16, "height": 16, "spp": 2}),
    );
    assert_eq!(r.status, 201, "{}", r.text());
    let j = wait_finished(
        &s,
        r.json()["id"].as_u64().unwrap(),
        Duration::from_secs(60),
    );
    assert_eq!(j["state"], "done", "{j}");
    // Again: refused, never overwritten.
    assert_eq!(
        upload(
            &s,
            "box.glb",
            b"glTF-something-else",
            "application/octet-stream"
        )
        .status,
        409
    );
    // A form post's content type is refused (cross-site forms can send it).
    assert_eq!(upload(&s, "x.glb", &glb, "text/plain").status, 415);
    assert_eq!(
        upload(&s, "x.glb", &glb, "multipart/form-data; boundary=x").status,
        415
    );
}

#[test]
fn hostile_uploads_are_refused_and_write_nothing_outside() {
    use std::io::Write as _;
    let s = start_with(None, &["--max-upload", "1"]);
    let zip = |name: &str| {
        let mut w = zip::ZipWriter::new(std::io::Cursor::new(Vec::new()));
        w.start_file(name, zip::write::SimpleFileOptions::default())
            .unwrap();
        w.write_all(b"[camera]\n").unwrap();
        w.finish().unwrap().into_inner()
    };
    let before = std::fs::read_dir(&s.root).unwrap().count();
    for (name, body, status, says) in [
        ("slip.zip", zip("../../slip.toml"), 400, "'..'"),
        ("abs.zip", zip("/tmp/abs.toml"), 400, "absolute"),
        ("../x.glb", b"glTF0000000000".to_vec(), 400, "file name"),
        ("x.exe", b"MZ".to_vec(), 400, ".glb"),
        ("big.glb", vec![0u8; 2 << 20], 413, "larger than"),
    ] {
        let r = upload(&s, name, &body, "application/zip");
        assert_eq!(r.status, status, "{name}: {}", r.text());
        assert!(
            r.json()["error"].as_str().unwrap().contains(says),
            "{name}: {}",
            r.text()
        );
    }
    assert!(!s.root.join("slip.toml").exists());
    assert!(!Path::new("/tmp/abs.toml").exists());
    assert_eq!(std::fs::read_dir(&s.root).unwrap().count(), before);
    // Nothing was left in the uploads folder either (no partial unpack, no temporary).
    let left: Vec<_> = std::fs::read_dir(s.root.join("scenes/uploads"))
        .map(|d| d.flatten().map(|e| e.file_name()).collect())
        .unwrap_or_default();
    assert!(left.is_empty(), "{left:?}");
}

#[test]
fn the_scene_list_hides_meshes_a_scene_uses_unless_asked() {
    let s = start();
    let scenes = s.root.join("scenes");
    std::fs::write(
        scenes.join("room.toml"),
        "[[object]]\nmesh = \"room-mesh.ply\"\n",
    )
    .unwrap();
    std::fs::write(scenes.join("room-mesh.ply"), "ply\n").unwrap();
    std::fs::write(scenes.join("loose.ply"), "ply\n").unwrap();
    let l = get(&s, "/api/scenes").json();
    assert_eq!(
        l["files"],
        json!([
            "alias.gltf",
            "fake.gltf",
            "room.toml",
            "sub/inner.obj",
            "loose.ply"
        ])
    );
    assert_eq!(l["hidden"], 1);
    let l = get(&s, "/api/scenes?all=true").json();
    assert_eq!(
        l["files"],
        json!([
            "alias.gltf",
            "fake.gltf",
            "room.toml",
            "sub/inner.obj",
            "loose.ply",
            "room-mesh.ply"
        ])
    );
    // The size a scene file asks for, and a clear error for a missing one.
    let d = get(&s, "/api/scene-defaults?scene=cornell").json();
    assert!(d["width"].as_u64().unwrap() > 0, "{d}");
    assert_eq!(d["variants"], json!([]), "{d}");
    // A glTF file's material variants (KHR_materials_variants), and those of a glTF file a TOML
    // scene includes: the names the `variant` field accepts, so the page can offer them.
    let triangle = "AAAAAAAAAAAAAAAAAACAPwAAAAAAAAAAAAAAAAAAgD8AAAAA";
    std::fs::write(
        scenes.join("variants.gltf"),
        format!(
            r#"{{"asset":{{"version":"2.0"}},
 "buffers":[{{"byteLength":36,"uri":"data:application/octet-stream;base64,{triangle}"}}],
 "bufferViews":[{{"buffer":0,"byteLength":36}}],
 "accessors":[{{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3","min":[0,0,0],"max":[1,1,0]}}],
 "materials":[{{}},{{}}],
 "meshes":[{{"primitives":[{{"attributes":{{"POSITION":0}},"material":0,
   "extensions":{{"KHR_materials_variants":{{"mappings":[{{"material":1,"variants":[1]}}]}}}}}}]}}],
 "nodes":[{{"mesh":0}}],"scenes":[{{"nodes":[0]}}],"scene":0,
 "extensionsUsed":["KHR_materials_variants"],
 "extensions":{{"KHR_materials_variants":{{"variants":[{{"name":"Day"}},{{"name":"Night"}}]}}}}}}"#
        ),
    )
    .unwrap();
    std::fs::write(
        scenes.join("with-variants.toml"),
        "[[object]]\ntype = \"mesh\"\nfile = \"variants.gltf\"\n",
    )
    .unwrap();
    for name in ["variants.gltf", "with-variants.toml"] {
        let d = get(&s, &format!("/api/scene-defaults?scene={name}")).json();
        assert_eq!(d["variants"], json!(["Day", "Night"]), "{name}: {d}");
    }
    let r = get(&s, "/api/scene-defaults?scene=nope.gltf");
    assert_eq!(r.status, 400);
    assert!(
        r.json()["error"]
            .as_str()
            .unwrap()
            .contains("no scene 'nope.gltf'"),
        "{}",
        r.text()
    );
}

#[test]
fn an_environment_map_from_the_scenes_folder_lights_the_render() {
    let s = start();
    let hdr = common::shared_dir().join("scenes/hdr/studio_small_03_1k.hdr");
    std::fs::create_dir_all(s.root.join("scenes/maps")).unwrap();
    std::fs::copy(&hdr, s.root.join("scenes/maps/studio.hdr")).unwrap();
    // Offered by the scene list; not offered as a scene.
    let l = get(&s, "/api/scenes").json();
    assert_eq!(l["environments"], json!(["maps/studio.hdr"]));
    assert!(
        !l["files"]
            .as_array()
            .unwrap()
            .contains(&json!("maps/studio.hdr"))
    );
    // Path safety as for scenes, and a scene file is not a map.
    for (bad, says) in [
        ("../secret.gltf", "'..'"),
        ("escape.gltf", "outside"),
        ("fake.gltf", "not an environment map"),
        ("nope.hdr", "no environment map 'nope.hdr'"),
    ] {
        let r = post_json(
            &s,
            "/api/renders",
            &json!({"scene": "cornell", "environment": bad}),
        );
        let m = field_error(&r, "environment");
        assert!(m.contains(says), "{bad}: {m}");
    }
    // The server's render equals the command line's with --env, and differs from no map.
    let base = json!({"scene": "cornell", "width": 24, "height": 24, "spp": 4, "max_depth": 3});
    let mut lit = base.clone();
    lit["environment"] = json!("maps/studio.hdr");
    lit["output"] = json!("lit");
    let (_, lit_exr) = server_render(&s, &lit);
    let mut plain = base.clone();
    plain["output"] = json!("plain");
    let (_, plain_exr) = server_render(&s, &plain);
    let map = s.root.join("scenes/maps/studio.hdr");
    let args = [
        "--width",
        "24",
        "--height",
        "24",
        "--spp",
        "4",
        "--max-depth",
        "3",
        "--env",
        map.to_str().unwrap(),
    ];
    let cli = cli_render(&s.root, "cornell", &args);
    assert_eq!(
        lit_exr, cli.1,
        "server EXR with the map differs from the CLI's --env"
    );
    assert_ne!(lit_exr, plain_exr, "the map did not change the render");
}

/// `/api/scene-view` reports the scene's bounds and the camera it renders with: a model without a
/// camera gets the framing camera, aimed at the centre of its bounds.
#[test]
fn the_scene_view_reports_bounds_and_the_framing_camera() {
    let s = start();
    let glb = common::shared_dir().join("scenes/gltf/Box/glTF-Binary/Box.glb");
    std::fs::copy(&glb, s.root.join("scenes/box.glb")).unwrap();
    let v = get(&s, "/api/scene-view?scene=box.glb");
    assert_eq!(v.status, 200, "{}", v.text());
    let v = v.json();
    let f = |x: &Value| -> Vec<f64> {
        x.as_array()
            .unwrap()
            .iter()
            .map(|n| n.as_f64().unwrap())
            .collect()
    };
    let (min, max) = (f(&v["bounds"]["min"]), f(&v["bounds"]["max"]));
    // Khronos' Box is the unit cube around the origin.
    for i in 0..3 {
        assert!(
            (min[i] + 0.5).abs() < 1e-4 && (max[i] - 0.5).abs() < 1e-4,
            "{v}"
        );
    }
    let (eye, target) = (f(&v["camera"]["eye"]), f(&v["camera"]["target"]));
    assert!(target.iter().all(|t| t.abs() < 1e-4), "target {target:?}");
    // The framing rule (`world::orbit_camera`): on +z, at the distance where the bounding sphere
    // (radius √3/2) fits a vertical field of view of 39.6°, plus a 5 % margin.
    let want = 3f64.sqrt() / 2.0 / (39.6f64.to_radians() / 2.0).sin() * 1.05;
    assert!(
        eye[0].abs() < 1e-4 && eye[1].abs() < 1e-4 && (eye[2] - want).abs() < 1e-4,
        "eye {eye:?}, want [0, 0, {want}]"
    );
    let fov = v["camera"]["fov"].as_f64().unwrap();
    assert!((fov - 39.6).abs() < 1e-4, "fov {fov}");
    // A built-in with its own camera reports that camera; a bad name is refused by name.
    let c = get(&s, "/api/scene-view?scene=cornell").json();
    assert!(
        c["bounds"]["min"].is_array() && c["camera"]["eye"].is_array(),
        "{c}"
    );
    let r = get(&s, "/api/scene-view?scene=../secret.gltf");
    assert_eq!(r.status, 400);
    assert!(r.text().contains(".."), "{}", r.text());
}

/// The `camera` field renders that view: the server's image equals the command line's with
/// `--camera-from` a TOML file holding the same camera, and differs from the scene's own
/// camera; cameras that cannot frame a view are refused by name.
#[test]
fn the_camera_field_renders_the_view_as_camera_from_does() {
    let s = start();
    let camera =
        json!({"eye": [0.25, 0.5, 2.5], "target": [0.0, 0.125, 0.0], "up": [0, 1, 0], "fov": 50});
    let base = json!({"scene": "cornell", "width": 20, "height": 16, "spp": 2, "max_depth": 3});
    let mut viewed = base.clone();
    viewed["camera"] = camera.clone();
    viewed["output"] = json!("viewed");
    let (_, viewed_exr) = server_render(&s, &viewed);
    let mut own = base.clone();
    own["output"] = json!("own");
    let (_, own_exr) = server_render(&s, &own);
    assert_ne!(
        viewed_exr, own_exr,
        "the camera field did not change the view"
    );
    let toml = s.root.join("cam.toml");
    std::fs::write(
        &toml,
        "[[camera]]\neye = [0.25, 0.5, 2.5]\ntarget = [0.0, 0.125, 0.0]\nup = [0.0, 1.0, 0.0]\nfov = 50.0\n",
    )
    .unwrap();
    let args = [
        "--width",
        "20",
        "--height",
        "16",
        "--spp",
        "2",
        "--max-depth",
        "3",
        "--camera-from",
        toml.to_str().unwrap(),
    ];
    let cli = cli_render(&s.root, "cornell", &args);
    assert_eq!(
        viewed_exr, cli.1,
        "server camera differs from --camera-from"
    );
    // The job reports the camera it rendered.
    let job = listed_job(&s, "viewed");
    assert_eq!(job["camera"]["fov"], 50.0);
    for (bad, says) in [
        (json!({"eye": [0, 0, 1], "target": [0, 0, 1]}), "same point"),
        (
            json!({"eye": [0, 0, 1], "target": [0, 0, 0], "fov": 0}),
            "fov",
        ),
        (
            json!({"eye": [0, 0, 1], "target": [0, 0, 0], "fov": 200}),
            "fov",
        ),
        (
            json!({"eye": [0, 0, 1], "target": [0, 0, 0], "up": [0, 0, 2]}),
            "up",
        ),
        (
            json!({"eye": [0, 0, 1], "target": [0, 0, 0], "up": [0, 0, 0]}),
            "up",
        ),
        (json!({"eye": [0, 0, 1]}), "target"),
        (json!({"eye": [0, 0], "target": [0, 0, 0]}), "eye"),
        (json!({"eye": [0, 0, "x"], "target": [0, 0, 0]}), "eye"),
        (json!({"eye": [1e30, 0, 1], "target": [0, 0, 0]}), "eye"),
        (
            json!({"eye": [0, 0, 1], "target": [0, 0, 0], "zoom": 2}),
            "zoom",
        ),
        (json!([0, 0, 1]), "object"),
    ] {
        let r = post_json(
            &s,
            "/api/renders",
            &json!({"scene": "cornell", "camera": bad}),
        );
        let m = field_error(&r, "camera");
        assert!(m.contains(says), "{bad}: {m}");
    }
}

/// The linear image the page tone-maps is the render's film exactly (the EXR's f32 values).
#[test]
fn the_linear_endpoint_serves_the_film_and_the_asked_layers() {
    let s = start();
    let body = json!({"scene": "cornell", "width": 12, "height": 10, "spp": 2, "max_depth": 3,
                      "output": "lin", "aovs": ["albedo", "normal"]});
    let (_, exr) = server_render(&s, &body);
    let id = get(&s, "/api/renders").json()["renders"][0]["id"]
        .as_u64()
        .unwrap();
    let lin = get(&s, &format!("/api/renders/{id}/linear"));
    assert_eq!(lin.status, 200);
    let floats: Vec<f32> = lin
        .body
        .chunks_exact(4)
        .map(|b| f32::from_le_bytes(b.try_into().unwrap()))
        .collect();
    let want: Vec<f32> = exr.data.iter().flat_map(|p| p.to_array()).collect();
    assert_eq!(floats, want);
    let header = |r: &Reply, k: &str| {
        r.headers
            .iter()
            .find(|(h, _)| h.eq_ignore_ascii_case(k))
            .map(|(_, v)| v.clone())
    };
    assert_eq!(header(&lin, "x-width").as_deref(), Some("12"));
    assert_eq!(header(&lin, "x-height").as_deref(), Some("10"));
    // The layers are the EXR's channels, interleaved.
    let exr_bytes = get(&s, &format!("/api/renders/{id}/image.exr")).body;
    let path = s.root.join("layers.exr");
    std::fs::write(&path, exr_bytes).unwrap();
    let (_, _, channels) = trayecto::film::output::read_exr_channels(&path).unwrap();
    for (layer, names) in [
        ("normal", ["normal.X", "normal.Y", "normal.Z"]),
        ("albedo", ["albedo.R", "albedo.G", "albedo.B"]),
    ] {
        let got = get_floats(&s, &format!("/api/renders/{id}/linear?layer={layer}"));
        let ch: Vec<&Vec<f32>> = names
            .iter()
            .map(|n| &channels.iter().find(|(c, _)| c == n).unwrap().1)
            .collect();
        let want: Vec<f32> = (0..120)
            .flat_map(|i| ch.iter().map(move |c| c[i]))
            .collect();
        assert_eq!(got, want, "{layer}");
        assert_ne!(got, floats, "{layer} is the beauty image");
    }
    // Not asked for: refused, as are unknown layers.
    assert_eq!(
        get(&s, &format!("/api/renders/{id}/linear?layer=denoised")).status,
        404
    );
    assert_eq!(
        get(&s, &format!("/api/renders/{id}/linear?layer=depth")).status,
        404
    );
    let r = post_json(
        &s,
        "/api/renders",
        &json!({"scene": "cornell", "aovs": ["depth"]}),
    );
    assert!(field_error(&r, "aovs").contains("albedo"));
}

/// The viewport: a view renders a quick first image, then refines to its samples; a new view
/// cancels the stale one at once (a view of 16384 samples per pixel is replaced by a small one
/// that finishes), previews take no place in the render queue (a final render with
/// `--max-jobs 1` runs beside a refining preview), and sessions are named safely.
#[test]
fn the_viewport_refines_and_a_new_view_replaces_the_stale_one() {
    let s = start_with(None, &["--max-jobs", "1"]);
    let status = |sid: &str| get(&s, &format!("/api/viewport/{sid}")).json();
    let wait = |sid: &str, generation: u64, states: &[&str]| -> Value {
        let t0 = Instant::now();
        loop {
            let st = status(sid);
            if st["generation"] == generation
                && states.contains(&st["state"].as_str().unwrap_or(""))
            {
                return st;
            }
            assert!(
                t0.elapsed() < Duration::from_secs(60),
                "viewport stuck: {st}"
            );
            std::thread::sleep(Duration::from_millis(20));
        }
    };
    let view = json!({"scene": "cornell", "width": 32, "height": 24, "spp": 8, "max_depth": 3});
    let r = post_json(&s, "/api/viewport?session=t1", &view);
    assert_eq!(r.status, 202, "{}", r.text());
    let g1 = r.json()["generation"].as_u64().unwrap();
    let st = wait("t1", g1, &["done"]);
    assert_eq!(st["samples"], 8);
    assert_eq!(
        (st["width"].as_u64(), st["height"].as_u64()),
        (Some(32), Some(24))
    );
    // The quarter-size first look came before the full-size passes (each counted as a version).
    assert!(st["version"].as_u64().unwrap() >= 2, "{st}");
    assert!(st["first_ms"].as_f64().unwrap() <= st["full_ms"].as_f64().unwrap());
    // Without a camera the scene's own view is used and reported for the orbit.
    assert!(st["view"]["camera"]["eye"].is_array() && st["view"]["bounds"]["min"].is_array());
    let lin = get(&s, "/api/viewport/t1/linear");
    assert_eq!(lin.status, 200);
    assert_eq!(lin.body.len(), 32 * 24 * 12);

    // A preview that would run for ever, replaced by a small one.
    let mut endless = view.clone();
    endless["spp"] = json!(16384);
    endless["width"] = json!(64);
    endless["height"] = json!(64);
    let g2 = post_json(&s, "/api/viewport?session=t1", &endless).json()["generation"]
        .as_u64()
        .unwrap();
    wait("t1", g2, &["refining"]);
    // A final render is not blocked by the preview (--max-jobs 1).
    let (png, _) = server_render(
        &s,
        &json!({"scene": "cornell", "width": 8, "height": 8, "spp": 1, "output": "beside"}),
    );
    assert!(!png.is_empty());
    let mut moved = view.clone();
    moved["camera"] = json!({"eye": [0.5, 0.5, 3], "target": [0, 0.25, 0]});
    let t0 = Instant::now();
    let g3 = post_json(&s, "/api/viewport?session=t1", &moved).json()["generation"]
        .as_u64()
        .unwrap();
    let st = wait("t1", g3, &["done"]);
    eprintln!("new view done {:?} after the request", t0.elapsed());
    assert_eq!(st["samples"], 8);
    // Previews are not render jobs.
    assert_eq!(
        get(&s, "/api/renders").json()["renders"]
            .as_array()
            .unwrap()
            .len(),
        1
    );

    // Bad requests and names.
    let bad = post_json(
        &s,
        "/api/viewport?session=t1",
        &json!({"scene": "cornell", "camera": {"eye": [0, 0, 0], "target": [0, 0, 0]}}),
    );
    assert!(field_error(&bad, "camera").contains("same point"));
    for sid in ["", "a/b", "..", &"x".repeat(65)] {
        let r = post_json(&s, &format!("/api/viewport?session={sid}"), &view);
        assert_eq!(r.status, 400, "session {sid:?}");
    }
    assert_eq!(get(&s, "/api/viewport/nobody").status, 404);
}

/// `env_rotation` turns the environment map as the command line's `--env-rotation` does, and
/// needs a map.
#[test]
fn env_rotation_turns_the_map_as_the_cli_does() {
    let s = start();
    let hdr = common::shared_dir().join("scenes/hdr/studio_small_03_1k.hdr");
    std::fs::copy(&hdr, s.root.join("scenes/studio.hdr")).unwrap();
    let base = json!({"scene": "cornell", "width": 16, "height": 16, "spp": 2, "max_depth": 2,
                      "environment": "studio.hdr"});
    let mut turned = base.clone();
    turned["env_rotation"] = json!(90);
    turned["output"] = json!("turned");
    let (_, turned_exr) = server_render(&s, &turned);
    let mut plain = base.clone();
    plain["output"] = json!("plain");
    let (_, plain_exr) = server_render(&s, &plain);
    assert_ne!(
        turned_exr, plain_exr,
        "the rotation did not change the render"
    );
    let map = s.root.join("scenes/studio.hdr").display().to_string();
    let args = [
        "--width",
        "16",
        "--height",
        "16",
        "--spp",
        "2",
        "--max-depth",
        "2",
        "--env",
        map.as_str(),
        "--env-rotation",
        "90",
    ];
    let cli = cli_render(&s.root, "cornell", &args);
    assert_eq!(
        turned_exr, cli.1,
        "server env_rotation differs from --env-rotation"
    );
    let r = post_json(
        &s,
        "/api/renders",
        &json!({"scene": "cornell", "env_rotation": 30}),
    );
    assert!(field_error(&r, "env_rotation").contains("environment"));
    let r = post_json(
        &s,
        "/api/renders",
        &json!({"scene": "cornell", "environment": "studio.hdr", "env_rotation": "x"}),
    );
    assert!(field_error(&r, "env_rotation").contains("degrees"));
}

/// `variant` (glTF KHR_materials_variants) picks the material variant for a render job and for
/// the viewport, as `--variant` does on the command line; an unknown name fails the job or the
/// view with the scene's variant names.
#[test]
fn the_variant_field_renders_as_the_cli_variant_flag_does() {
    let s = start();
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/gltf-files/quad_variants.gltf");
    std::fs::copy(&src, s.root.join("scenes/quad_variants.gltf")).unwrap();
    // The quad fills the view: blue by default, red and green as its variants.
    let base = json!({"scene": "quad_variants.gltf", "width": 16, "height": 16, "spp": 4,
                      "max_depth": 2, "seed": 0});
    let job = |variant: Option<&str>| {
        let mut b = base.clone();
        b["output"] = json!(format!("v-{}", variant.unwrap_or("default")));
        if let Some(v) = variant {
            b["variant"] = json!(v);
        }
        b
    };
    // Which channel leads the others by 20 %: 0 red, 1 green, 2 blue.
    let lead = |m: [f32; 3]| (0..3).find(|&k| (0..3).all(|j| j == k || m[k] > 1.2 * m[j]));
    let (_, default) = server_render(&s, &job(None));
    let (_, green) = server_render(&s, &job(Some("Green")));
    let (_, red) = server_render(&s, &job(Some("Red")));
    assert_eq!(
        lead(default.mean().to_array()),
        Some(2),
        "{:?}",
        default.mean()
    );
    assert_eq!(lead(green.mean().to_array()), Some(1), "{:?}", green.mean());
    assert_eq!(lead(red.mean().to_array()), Some(0), "{:?}", red.mean());
    // The same image as the command line's --variant.
    let args: Vec<String> = [
        "--width",
        "16",
        "--height",
        "16",
        "--spp",
        "4",
        "--max-depth",
        "2",
        "--seed",
        "0",
        "--variant",
        "Green",
    ]
    .iter()
    .map(|a| a.to_string())
    .collect();
    let scene = s.root.join("scenes/quad_variants.gltf");
    let cli = cli_render(&s.root, scene.to_str().unwrap(), &args);
    assert_eq!(
        green, cli.1,
        "server EXR with variant Green differs from --variant Green"
    );
    // The job reports its variant.
    let listed = listed_job(&s, "v-Green");
    assert_eq!(listed["variant"], "Green", "{listed}");
    // An unknown name fails the job, naming the variants there are.
    let r = post_json(&s, "/api/renders", &job(Some("Purple")));
    assert_eq!(r.status, 201, "{}", r.text());
    let j = wait_finished(
        &s,
        r.json()["id"].as_u64().unwrap(),
        Duration::from_secs(60),
    );
    let e = j["error"].as_str().unwrap_or("");
    assert!(
        j["state"] == "failed" && e.contains("'Purple'") && e.contains("'Red', 'Green'"),
        "{j}"
    );

    // The viewport: the same variants, the same refusal.
    let view = |variant: Value| {
        let mut v = json!({"scene": "quad_variants.gltf", "width": 16, "height": 16, "spp": 2,
                           "max_depth": 2});
        v["variant"] = variant;
        let r = post_json(&s, "/api/viewport?session=variants", &v);
        assert_eq!(r.status, 202, "{}", r.text());
        let generation = r.json()["generation"].clone();
        let t0 = Instant::now();
        loop {
            let st = get(&s, "/api/viewport/variants").json();
            if st["generation"] == generation
                && matches!(st["state"].as_str(), Some("done" | "failed"))
            {
                if st["state"] == "failed" {
                    return Err(st["error"].as_str().unwrap_or("").to_string());
                }
                let lin = get(&s, "/api/viewport/variants/linear").body;
                let mut m = [0f32; 3];
                for (i, c) in lin.chunks_exact(4).enumerate() {
                    m[i % 3] += f32::from_le_bytes(c.try_into().unwrap());
                }
                return Ok(m);
            }
            assert!(
                t0.elapsed() < Duration::from_secs(60),
                "viewport stuck: {st}"
            );
            std::thread::sleep(Duration::from_millis(20));
        }
    };
    assert_eq!(lead(view(json!("Green")).unwrap()), Some(1));
    assert_eq!(lead(view(json!("Red")).unwrap()), Some(0));
    assert_eq!(lead(view(Value::Null).unwrap()), Some(2));
    let e = view(json!("Purple")).unwrap_err();
    assert!(
        e.contains("'Purple'") && e.contains("'Red', 'Green'"),
        "{e}"
    );
}

/// The size of a finished job's PNG.
fn png_size(s: &Server, job: &Value) -> (u32, u32) {
    let png = get(s, job["png"].as_str().unwrap());
    assert_eq!(png.status, 200);
    (
        u32::from_be_bytes(png.body[16..20].try_into().unwrap()),
        u32::from_be_bytes(png.body[20..24].try_into().unwrap()),
    )
}

/// API paper cuts: a request without `output` gets a name of its own, `render-ID` (it used to be
/// `render` every time, so a second such request got 409), skipping a name an earlier run of the
/// server left in the output folder; and a request without a size gets the command line's rule
/// (the scene file's resolution, else its camera's shape at 512 high, else 512²) — the size
/// `/api/scene-defaults` reports — where it used to be 256² always.
#[test]
fn requests_without_output_or_size_get_unique_names_and_the_cli_size() {
    let root = fixture();
    let scenes = root.join("scenes");
    std::fs::write(
        scenes.join("wide.toml"),
        "[render]\nwidth = 48\nheight = 20\n\n[[material]]\nname = \"white\"\n\
         base_color = [0.8, 0.8, 0.8]\n\n[[object]]\nname = \"ball\"\ntype = \"sphere\"\n\
         center = [0.0, 0.0, 0.0]\nradius = 1.0\nmaterial = \"white\"\n",
    )
    .unwrap();
    let s = start_with(Some(&scenes), &[]);
    let run = |body: Value| {
        let r = post_json(&s, "/api/renders", &body);
        assert_eq!(r.status, 201, "{body}: {}", r.text());
        let id = r.json()["id"].as_u64().unwrap();
        let j = wait_finished(&s, id, Duration::from_secs(120));
        assert_eq!(j["state"], "done", "{j}");
        (id, j)
    };
    // The same request twice: two renders, two names.
    let body = json!({"scene": "cornell", "spp": 1, "max_depth": 1});
    let (a, ja) = run(body.clone());
    let (b, jb) = run(body.clone());
    assert_eq!(ja["output"], format!("render-{a}"));
    assert_eq!(jb["output"], format!("render-{b}"));
    // The Cornell box's camera is square: 512², as `trayecto render cornell` gives.
    assert_eq!(png_size(&s, &ja), (512, 512));
    // A name left by an earlier run is skipped, never overwritten.
    let next = b + 1;
    let old = s.root.join(format!("out/render-{next}.png"));
    std::fs::write(&old, b"an earlier run's image").unwrap();
    let small = json!({"scene": "cornell", "width": 8, "height": 8, "spp": 1});
    let (c, jc) = run(small);
    assert_eq!(c, next);
    assert_eq!(jc["output"], format!("render-{next}-2"));
    assert_eq!(std::fs::read(&old).unwrap(), b"an earlier run's image");
    // An explicit name is still refused when taken.
    let r = post_json(
        &s,
        "/api/renders",
        &json!({"scene": "cornell", "output": format!("render-{a}"), "width": 8, "height": 8}),
    );
    assert_eq!(r.status, 409, "{}", r.text());
    // The scene file's resolution, as /api/scene-defaults says; one side given keeps its shape.
    let d = get(&s, "/api/scene-defaults?scene=wide.toml").json();
    assert_eq!(
        (d["width"].clone(), d["height"].clone()),
        (json!(48), json!(20))
    );
    let (_, j) = run(json!({"scene": "wide.toml", "spp": 1, "max_depth": 1}));
    assert_eq!(png_size(&s, &j), (48, 20));
    let (_, j) = run(json!({"scene": "wide.toml", "width": 96, "spp": 1, "max_depth": 1}));
    assert_eq!(png_size(&s, &j), (96, 40));
    // A scene that cannot be loaded is named when its size is needed.
    let r = post_json(&s, "/api/renders", &json!({"scene": "fake.gltf"}));
    assert!(
        field_error(&r, "scene").contains("fake.gltf"),
        "{}",
        r.text()
    );
    std::fs::remove_dir_all(root).ok();
}

/// `"aovs": ["samples", "variance"]`: the server's EXR carries `samples.Y` (the spp
/// everywhere on a uniform render) and `variance.Y`, bit-identical to the command line's
/// `--aov samples,variance`, and `/linear?layer=` serves them as grey RGB.
#[test]
fn the_sample_and_variance_layers_are_served_as_the_cli_writes_them() {
    let s = start();
    let body = json!({"scene": "cornell", "output": "stats", "width": 10, "height": 8, "spp": 3,
                      "max_depth": 4, "aovs": ["samples", "variance"]});
    server_render(&s, &body);
    let j = listed_job(&s, "stats");
    let id = j["id"].as_u64().unwrap();
    let path = s.root.join("stats-fetched.exr");
    std::fs::write(&path, get(&s, &format!("/api/renders/{id}/image.exr")).body).unwrap();
    let (_, _, server) = trayecto::film::output::read_exr_channels(&path).unwrap();
    let dir = s.root.join("cli");
    std::fs::create_dir_all(&dir).unwrap();
    let args = [
        "--width",
        "10",
        "--height",
        "8",
        "--spp",
        "3",
        "--max-depth",
        "4",
        "--aov",
        "samples,variance",
    ];
    cli_render(&dir, "cornell", &args);
    let (_, _, cli) = trayecto::film::output::read_exr_channels(&dir.join("cli.exr")).unwrap();
    let channel = |chans: &[(String, Vec<f32>)], name: &str| {
        chans
            .iter()
            .find(|(n, _)| n == name)
            .unwrap_or_else(|| panic!("no channel {name}"))
            .1
            .clone()
    };
    assert!(channel(&server, "samples.Y").iter().all(|&c| c == 3.0));
    let variance = channel(&server, "variance.Y");
    assert!(variance.iter().any(|&v| v > 0.0));
    assert_eq!(
        variance.iter().map(|v| v.to_bits()).collect::<Vec<_>>(),
        channel(&cli, "variance.Y")
            .iter()
            .map(|v| v.to_bits())
            .collect::<Vec<_>>()
    );
    // Side files beside the CLI's PNG.
    assert!(dir.join("cli.samples.png").is_file() && dir.join("cli.variance.png").is_file());
    for (layer, want) in [("samples", vec![3.0; 80]), ("variance", variance)] {
        let got = get_floats(&s, &format!("/api/renders/{id}/linear?layer={layer}"));
        let want: Vec<f32> = want.iter().flat_map(|&v| [v; 3]).collect();
        assert_eq!(got, want, "{layer}");
    }
}

/// Issue #16: a scene whose camera is not a perspective one (pbrt-v4's orthographic camera with
/// an off-centre screen window) renders through the server exactly as the command line renders
/// the file, both as a final render and in the viewport, as long as the request carries no
/// `camera` (the page sends none until the user moves the view). The scene view reports the
/// projection so the page can say when an orbit turns it into a perspective view, and the
/// orbit's perspective camera does not reproduce the scene's image. The viewport's image equals
/// the command line's bit for bit only with the file's pixel filter (pbrt-v4's default Gaussian
/// here, the file having no `PixelFilter`), so this also checks the viewport uses it.
#[test]
fn an_orthographic_scene_camera_renders_as_the_cli_does() {
    let s = start();
    let file =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/pbrt/orthographic.pbrt");
    std::fs::copy(&file, s.root.join("scenes/ortho.pbrt")).unwrap();
    let scene = s.root.join("scenes/ortho.pbrt");
    let (w, h, spp, depth) = (64, 48, 4, 5);
    let args = [
        "--width",
        "64",
        "--height",
        "48",
        "--spp",
        "4",
        "--max-depth",
        "5",
    ];
    let (_, cli) = cli_render(&s.root, scene.to_str().unwrap(), &args);

    let view = get(&s, "/api/scene-view?scene=ortho.pbrt");
    assert_eq!(view.status, 200, "{}", view.text());
    let view = view.json();
    assert_eq!(view["projection"], "orthographic", "{view}");

    let base =
        json!({"scene": "ortho.pbrt", "width": w, "height": h, "spp": spp, "max_depth": depth});
    let mut own = base.clone();
    own["output"] = json!("own");
    let (_, own_exr) = server_render(&s, &own);
    assert_eq!(
        own_exr, cli,
        "the final render differs from the command line's"
    );

    // The perspective camera the orbit starts from is another image (what the page used to send).
    let mut orbit = base.clone();
    orbit["output"] = json!("orbit");
    orbit["camera"] = view["camera"].clone();
    let (_, orbit_exr) = server_render(&s, &orbit);
    assert_ne!(
        orbit_exr, cli,
        "the orbit's camera rendered the orthographic image"
    );

    // The viewport without a camera refines to the command line's film.
    let r = post_json(&s, "/api/viewport?session=ortho", &base);
    assert_eq!(r.status, 202, "{}", r.text());
    let generation = r.json()["generation"].as_u64().unwrap();
    let t0 = Instant::now();
    loop {
        let st = get(&s, "/api/viewport/ortho").json();
        if st["generation"] == generation && st["state"] == "done" {
            assert_eq!(st["view"]["projection"], "orthographic", "{st}");
            break;
        }
        assert_ne!(st["state"], "failed", "{st}");
        assert!(
            t0.elapsed() < Duration::from_secs(60),
            "viewport stuck: {st}"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    let got = get_floats(&s, "/api/viewport/ortho/linear");
    let want: Vec<f32> = cli.data.iter().flat_map(|p| p.to_array()).collect();
    assert_eq!(got.len(), want.len());
    assert!(
        got == want,
        "the viewport's image differs from the command line's"
    );
}

/// A zip of `entries`, then with every `from` in its names (local headers and central directory
/// alike) replaced by `to` of the same length: the writer refuses repeated names, a hostile
/// archive does not.
fn patched_zip(entries: &[(&str, &[u8])], from: &[u8], to: &[u8]) -> Vec<u8> {
    use std::io::Write as _;
    let mut w = zip::ZipWriter::new(std::io::Cursor::new(Vec::new()));
    for (name, data) in entries {
        w.start_file(*name, zip::write::SimpleFileOptions::default())
            .unwrap();
        w.write_all(data).unwrap();
    }
    let mut z = w.finish().unwrap().into_inner();
    assert_eq!(from.len(), to.len());
    for i in 0..z.len() - from.len() {
        if &z[i..i + from.len()] == from {
            z[i..i + from.len()].copy_from_slice(to);
        }
    }
    z
}

/// Repeated entry names (which the zip crate would collapse to the last) and a file where a
/// folder must go (`a` beside `a/b.toml`) are refused with 400, from the archive's raw names.
#[test]
fn repeated_and_clashing_upload_entries_are_refused_with_400() {
    let s = start();
    let scene = b"[camera]\nposition = [0, 0, 5]\n";
    let dup = patched_zip(
        &[("scene.toml", scene), ("other.toml", b"[camera]\n")],
        b"other.toml",
        b"scene.toml",
    );
    let clash = patched_zip(&[("a", b"x"), ("a/b.toml", scene)], b"-", b"-");
    let case = patched_zip(&[("x/s.toml", scene), ("X/S.toml", scene)], b"-", b"-");
    for (name, body, says) in [
        ("dup.zip", dup, "appears twice"),
        ("clash.zip", clash, "needs a folder"),
        ("case.zip", case, "appears twice"),
    ] {
        let r = upload(&s, name, &body, "application/zip");
        assert_eq!(r.status, 400, "{name}: {}", r.text());
        assert!(
            r.json()["error"].as_str().unwrap().contains(says),
            "{name}: {}",
            r.text()
        );
    }
    let left: Vec<_> = std::fs::read_dir(s.root.join("scenes/uploads"))
        .map(|d| d.flatten().map(|e| e.file_name()).collect())
        .unwrap_or_default();
    assert!(left.is_empty(), "{left:?}");
}

/// Every answer, refusals included, forbids framing by other sites and sending the address as
/// Referer.
#[test]
fn every_response_forbids_framing_and_referrers() {
    let s = start();
    let t = start_with(None, &["--host", "127.0.0.2"]);
    // A foreign Host (refused with 403 before any handler).
    let mut c = TcpStream::connect(s.addr).unwrap();
    c.write_all(
        b"GET /api/options HTTP/1.1\r\nHost: evil.example:8080\r\nConnection: close\r\n\r\n",
    )
    .unwrap();
    let mut buf = Vec::new();
    c.read_to_end(&mut buf).unwrap();
    let foreign = parse_reply(&buf);
    assert_eq!(foreign.status, 403);
    for r in [
        get(&s, "/"),
        get(&s, "/api/options"),
        get(&s, "/no/such/page"),
        foreign,
        get(&t, "/api/options"),
    ] {
        let csp = r.header("content-security-policy").unwrap_or("");
        assert!(
            csp.contains("frame-ancestors 'none'"),
            "{}: {csp}",
            r.status
        );
        assert_eq!(r.header("x-frame-options"), Some("DENY"), "{}", r.status);
        assert_eq!(
            r.header("referrer-policy"),
            Some("no-referrer"),
            "{}",
            r.status
        );
    }
}

/// The Authorization scheme is case-insensitive: "bearer" works as "Bearer" does.
#[test]
fn a_lowercase_bearer_scheme_is_accepted() {
    let s = start_with(None, &["--host", "127.0.0.2"]);
    let token = s.token.clone().unwrap();
    for scheme in ["bearer", "BEARER", "Bearer"] {
        let r = get_with(
            &s,
            "/api/options",
            &format!("Authorization: {scheme} {token}\r\n"),
        );
        assert_eq!(r.status, 200, "{scheme}: {}", r.text());
    }
    let r = get_with(
        &s,
        "/api/options",
        &format!("Authorization: Basic {token}\r\n"),
    );
    assert_eq!(r.status, 401);
}

/// A job's log names the files of the scenes folder relative to it, never by the server's path.
#[test]
fn job_logs_name_scenes_relative_to_the_scenes_folder() {
    let s = start();
    let scenes = s.root.join("scenes").canonicalize().unwrap();
    std::fs::create_dir_all(scenes.join("warn")).unwrap();
    std::fs::write(
        scenes.join("warn/main.pbrt"),
        "Camera \"perspective\"\nWorldBegin\nInclude \"inc.pbrt\"\n",
    )
    .unwrap();
    std::fs::write(
        scenes.join("warn/inc.pbrt"),
        "Shape \"sphere\" \"float radius\" 1 \"float bogus\" 2\n",
    )
    .unwrap();
    let r = post_json(
        &s,
        "/api/renders",
        &json!({"scene": "warn/main.pbrt", "output": "warn", "width": 8, "height": 8, "spp": 1}),
    );
    assert_eq!(r.status, 201, "{}", r.text());
    let j = wait_finished(
        &s,
        r.json()["id"].as_u64().unwrap(),
        Duration::from_secs(60),
    );
    assert_eq!(j["state"], "done", "{j}");
    let log = j["log"].to_string();
    assert!(log.contains("warn/inc.pbrt:1"), "{log}");
    let root = s.root.canonicalize().unwrap();
    assert!(!log.contains(&*root.to_string_lossy()), "{log}");
}

/// The page starts from the command line's defaults (64 bounces, 64 spp, the PNG view
/// transform); only equirectangular images are offered as environment maps (not a reference
/// render that happens to be an EXR); and a served scene still may not read outside the scenes
/// folder, which the command line now allows.
#[test]
fn the_page_shares_the_cli_defaults_lists_maps_by_content_and_confines_scenes() {
    let s = start();
    let o = get(&s, "/api/options").json();
    assert_eq!(o["defaults"]["max_depth"], 64, "{o}");
    assert_eq!(o["defaults"]["spp"], 64, "{o}");
    assert_eq!(o["defaults"]["tonemap"], "pbr-neutral", "{o}");
    assert!(
        o["tonemaps"]
            .as_array()
            .unwrap()
            .contains(&json!("pbr-neutral"))
    );

    let scenes = s.root.join("scenes");
    let hdr = common::shared_dir().join("scenes/hdr/studio_small_03_1k.hdr");
    std::fs::copy(&hdr, scenes.join("studio.hdr")).unwrap();
    let reference = trayecto::film::Image {
        width: 16,
        height: 16,
        data: vec![trayecto::math::Vec3::splat(0.5); 256],
    };
    trayecto::film::output::write_image(
        &reference,
        &scenes.join("reference.exr"),
        1.0,
        Default::default(),
    )
    .unwrap();
    let l = get(&s, "/api/scenes").json();
    assert_eq!(l["environments"], json!(["studio.hdr"]), "{l}");

    // A served scene naming a mesh above the scenes folder is refused, as before.
    std::fs::copy(
        concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/twin/cube.ply"),
        s.root.join("cube.ply"),
    )
    .unwrap();
    std::fs::write(
        scenes.join("up.toml"),
        "[[object]]\ntype = \"mesh\"\nfile = \"../cube.ply\"\n",
    )
    .unwrap();
    let r = post_json(
        &s,
        "/api/renders",
        &json!({"scene": "up.toml", "width": 8, "height": 8, "spp": 1}),
    );
    assert_eq!(r.status, 201, "{}", r.text());
    let id = r.json()["id"].as_u64().unwrap();
    let j = wait_finished(&s, id, Duration::from_secs(60));
    assert_eq!(j["state"], "failed", "{j}");
    assert!(j.to_string().contains("'..'"), "{j}");
}

/// The page's "… left" is the renderer's estimate (`render::remaining_time`, the CLI's too):
/// for a frame whose lowest row of tiles is dense fog and the rest empty sky (tiles differ in
/// cost by orders of magnitude, and go top to bottom), the end it predicts at 30 and 60 % of
/// the render phase is within 20 % of the phase's length of the real end. Extrapolating the work
/// fraction, as the API did before, ended a third too early mid-way.
#[test]
fn the_time_left_is_the_renderers_estimate() {
    let root = fixture();
    std::fs::write(
        root.join("scenes/fog.toml"),
        "[[camera]]\neye = [0.0, 0.0, 4.0]\ntarget = [0.0, 0.0, 0.0]\nfov = 40.0\n\
         [[medium]]\nname = \"fog\"\nsigma_a = [0.0, 0.0, 0.0]\nsigma_s = [60.0, 60.0, 60.0]\n\
         [[material]]\nname = \"air\"\nmodel = \"interface\"\n\
         [[object]]\nname = \"fog\"\ntype = \"box\"\nmin = [-5.0, -5.0, 0.5]\nmax = [5.0, -0.55, 1.0]\n\
         material = \"air\"\nmedium_inside = \"fog\"\n",
    )
    .unwrap();
    let s = start_with(Some(&root.join("scenes")), &[]);
    // One render judged at 30 and 60 % of its render phase: the first miss's message.
    let measure = |attempt: u32| -> Result<(), String> {
        let r = post_json(
            &s,
            "/api/renders",
            &json!({"scene": "fog.toml", "output": format!("fog-{attempt}.png"), "width": 64,
                    "height": 64, "spp": 64}),
        );
        assert_eq!(r.status, 201, "{}", r.text());
        let id = r.json()["id"].as_u64().unwrap();
        // (elapsed, predicted end) while rendering, in the job's clock.
        let mut polls = Vec::new();
        let t0 = Instant::now();
        let end = loop {
            let j = get(&s, &format!("/api/renders/{id}")).json();
            let elapsed = j["elapsed_s"].as_f64().unwrap();
            if j["state"] == "rendering"
                && let Some(left) = j["remaining_s"].as_f64()
            {
                polls.push((elapsed, elapsed + left));
            } else if j["state"] != "rendering" && !polls.is_empty() {
                break elapsed;
            }
            assert!(j["active"] == true || !polls.is_empty(), "{j}");
            assert!(
                t0.elapsed() < Duration::from_secs(120),
                "still running: {j}"
            );
            std::thread::sleep(Duration::from_millis(20));
        };
        let j = wait_finished(&s, id, Duration::from_secs(60));
        let render_s = j["timings"]
            .as_array()
            .unwrap()
            .iter()
            .find(|t| t["phase"] == "render")
            .unwrap()["seconds"]
            .as_f64()
            .unwrap();
        assert!(
            render_s > 0.3,
            "the render took {render_s} s: too short to time"
        );
        let start = end - render_s;
        // (The 10 % mark is checked in-process by tests/first_hour.rs, on the CPU clock: here
        // the job's clock and 20 ms polls over HTTP blur the first fifth of a second.)
        for mark in [0.3, 0.6] {
            let &(t, predicted) = polls
                .iter()
                .find(|p| p.0 >= start + mark * render_s)
                .unwrap_or_else(|| panic!("no poll after {mark} of the render: {polls:?}"));
            if (predicted - end).abs() > 0.2 * render_s {
                return Err(format!(
                    "at {t:.2} s the end was predicted at {predicted:.2} s; it came at \
                     {end:.2} s (render phase {render_s:.2} s)"
                ));
            }
        }
        Ok(())
    };
    // This is the wall clock, shared with the other tests of this file running beside it: a
    // burst of their work mid-render stretches it in a way no estimate foresees. A miss is
    // measured again, up to three renders; three misses fail.
    let mut verdict = measure(1);
    for attempt in 2..=3 {
        match &verdict {
            Err(e) => eprintln!("render {}: {e}; measuring again", attempt - 1),
            Ok(()) => break,
        }
        verdict = measure(attempt);
    }
    if let Err(e) = verdict {
        panic!("{e}");
    }
}

/// `transparent` is `--transparent` for the page: the PNG comes back RGBA with the background
/// left out (alpha 0 in the corner, 255 on the model), the job says so, and a value that is not
/// a boolean or an integrator that cannot leave the background out is refused by field.
#[test]
fn a_transparent_render_gives_rgba() {
    let root = fixture();
    std::fs::write(
        root.join("scenes/ball.toml"),
        "[[camera]]\neye = [0.0, 0.0, 4.0]\ntarget = [0.0, 0.0, 0.0]\nfov = 40.0\n\
         [[object]]\ntype = \"sphere\"\ncenter = [0.0, 0.0, 0.0]\nradius = 0.8\n",
    )
    .unwrap();
    let s = start_with(Some(&root.join("scenes")), &[]);
    let r = post_json(
        &s,
        "/api/renders",
        &json!({"scene": "ball.toml", "output": "ball.png", "width": 16, "height": 16,
                "spp": 4, "transparent": true}),
    );
    assert_eq!(r.status, 201, "{}", r.text());
    let j = wait_finished(
        &s,
        r.json()["id"].as_u64().unwrap(),
        Duration::from_secs(60),
    );
    assert_eq!(j["state"], "done", "{j}");
    assert_eq!(j["transparent"], true);
    let png = get(&s, j["png"].as_str().unwrap());
    let img = image::load_from_memory(&png.body).unwrap();
    assert!(img.color().has_alpha(), "{:?}", img.color());
    let rgba = img.to_rgba8();
    assert_eq!(rgba.get_pixel(0, 0)[3], 0);
    assert_eq!(rgba.get_pixel(8, 8)[3], 255);
    for (body, field) in [
        (
            json!({"scene": "cornell", "transparent": "yes"}),
            "transparent",
        ),
        (
            json!({"scene": "cornell", "transparent": true, "integrator": "whitted"}),
            "transparent",
        ),
    ] {
        let r = post_json(&s, "/api/renders", &body);
        assert_eq!(r.status, 400, "{}", r.text());
        assert!(!field_error(&r, field).is_empty(), "{}", r.text());
    }
}

/// A sequence from the page (`frames`, `fps`): each frame is its own PNG and EXR, served as it
/// is written, and equal to the command line's `--frame N --fps F` render of the same file; a
/// `time` and a `shutter` reach the render as `--time`/`--shutter` do; conflicting moments and
/// bad ranges are refused per field.
#[test]
fn a_frame_range_renders_each_frame_as_the_command_line_does() {
    let shared = common::shared_dir().join("scenes");
    let scene = "gltf-anim/BoxAnimated/glTF-Binary/BoxAnimated.glb";
    let s = start_with(Some(&shared), &[]);
    let base = json!({"scene": scene, "width": 16, "height": 12, "spp": 2, "max_depth": 4,
                      "integrator": "path", "tonemap": "clamp", "seed": 0});
    let common_args = [
        "--width",
        "16",
        "--height",
        "12",
        "--spp",
        "2",
        "--max-depth",
        "4",
        "--tonemap",
        "clamp",
        "--seed",
        "0",
    ];
    let scene_path = shared.join(scene);
    let scene_arg = scene_path.to_str().unwrap();

    let mut body = base.clone();
    body["output"] = json!("seq");
    body["frames"] = json!([2, 4]);
    body["fps"] = json!(6);
    let r = post_json(&s, "/api/renders", &body);
    assert_eq!(r.status, 201, "{}", r.text());
    let id = r.json()["id"].as_u64().unwrap();
    let j = wait_finished(&s, id, Duration::from_secs(120));
    assert_eq!(j["state"], "done", "{j}");
    let done = j["frames"]["done"].as_array().unwrap();
    assert_eq!(
        done.iter()
            .map(|f| f["frame"].as_u64().unwrap())
            .collect::<Vec<_>>(),
        [2, 3, 4],
        "{j}"
    );
    let mut images = Vec::new();
    for f in done {
        let n = f["frame"].as_u64().unwrap().to_string();
        let exr = get(&s, f["exr"].as_str().unwrap());
        assert_eq!(exr.status, 200, "frame {n}");
        let path = s.root.join(format!("fetched-seq-{n}.exr"));
        std::fs::write(&path, &exr.body).unwrap();
        let server = trayecto::film::output::read_exr(&path).unwrap();
        let mut args: Vec<&str> = common_args.to_vec();
        args.extend(["--frame", &n, "--fps", "6"]);
        let cli = cli_render(&s.root, scene_arg, &args);
        assert_eq!(
            server, cli.1,
            "frame {n}: the server's EXR differs from the CLI's"
        );
        let png = get(&s, f["png"].as_str().unwrap());
        assert_eq!(decode_png(&png.body), decode_png(&cli.0), "frame {n}: PNG");
        let named = format!("seq_{:04}.png", f["frame"].as_u64().unwrap());
        assert!(
            png.header("content-disposition")
                .is_some_and(|h| h.contains(&named)),
            "frame {n}: downloads as {:?}, not {named}",
            png.header("content-disposition")
        );
        images.push(server);
    }
    assert_ne!(
        images[0], images[2],
        "the animation did not move between frames 2 and 4"
    );
    // The image shown and served as the job's own is the last frame.
    let last = get(&s, j["exr"].as_str().unwrap());
    assert_eq!(last.status, 200);
    assert_eq!(
        Some(last.body.as_slice()),
        std::fs::read(s.root.join("fetched-seq-4.exr"))
            .ok()
            .as_deref()
    );

    // A moment and a shutter, as --time and --shutter.
    let mut body = base.clone();
    body["output"] = json!("blurred");
    body["time"] = json!(0.4);
    body["shutter"] = json!([0.0, 0.2]);
    let (_, server) = server_render(&s, &body);
    let mut args: Vec<&str> = common_args.to_vec();
    args.extend(["--time", "0.4", "--shutter", "0,0.2"]);
    let cli = cli_render(&s.root, scene_arg, &args);
    assert_eq!(
        server, cli.1,
        "time and shutter: the server's EXR differs from the CLI's"
    );

    for (fields, field) in [
        (json!({"frames": [4, 2]}), "frames"),
        (json!({"frames": 3}), "frames"),
        (json!({"time": 1.0, "frames": [0, 1]}), "frames"),
        (json!({"frame": -1}), "frame"),
        (json!({"fps": 0}), "fps"),
        (json!({"shutter": [1.0, 0.5]}), "shutter"),
        (json!({"frames": [0, 100000], "spp": 1}), "frames"),
    ] {
        let mut body = base.clone();
        for (k, v) in fields.as_object().unwrap() {
            body[k] = v.clone();
        }
        let r = post_json(&s, "/api/renders", &body);
        assert!(!field_error(&r, field).is_empty(), "{fields}: {}", r.text());
    }
}
