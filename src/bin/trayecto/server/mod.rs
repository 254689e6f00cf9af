//! `trayecto serve`: the thesis's GUI (§5.5, Annex B) as a web page with a progressive preview
//! (docs/DESIGN.md §2, web UI). An axum server on 127.0.0.1 by default serves the embedded page and a small
//! JSON API (documented in the README); renders run on their own threads ([`jobs`]) and every
//! request is checked before any work starts ([`request`]).
//!
//! The server never reads a path taken from a URL: static files are embedded, downloads are looked
//! up by job id, and scene names are resolved only inside the canonical scenes folder.

// Handlers return an early `Response` as the error of small helpers; its size does not matter
// once per HTTP request.
#![allow(clippy::result_large_err)]

pub mod jobs;
pub mod request;

use axum::Router;
use axum::body::Body;
use axum::extract::{Path as UrlPath, Query, Request, State};
use axum::http::{HeaderMap, HeaderValue, Method, StatusCode, header};
use axum::middleware::{self, Next};
use axum::response::{IntoResponse, Response};
use axum::routing::{get, post};
use http_body_util::BodyExt;
use jobs::{Jobs, SubmitError};
use request::{Limits, Policy, RequestError};
use serde_json::{Value, json};
use std::net::SocketAddr;
use std::path::PathBuf;
use std::sync::Arc;

const INDEX_HTML: &str = include_str!(concat!(env!("CARGO_MANIFEST_DIR"), "/web/index.html"));
const APP_JS: &str = include_str!(concat!(env!("CARGO_MANIFEST_DIR"), "/web/app.js"));
const STYLE_CSS: &str = include_str!(concat!(env!("CARGO_MANIFEST_DIR"), "/web/style.css"));
/// Finished renders listed on the page (older ones are forgotten, their files stay on disk).
const HISTORY: usize = 10;
/// How much of an oversized body is read and dropped before answering 413.
const DRAIN_MAX: usize = 1 << 20;

#[derive(clap::Args, Debug, Clone)]
pub struct ServeArgs {
    /// Address to listen on; the default only accepts connections from this machine.
    #[arg(long, default_value = "127.0.0.1")]
    pub host: String,
    /// Port to listen on (0 picks a free one; the address is printed).
    #[arg(long, default_value_t = 8080)]
    pub port: u16,
    /// Folder whose scene files the page offers (only built-in scenes without it).
    #[arg(long)]
    pub scenes: Option<PathBuf>,
    /// Folder the renders are written to (created if missing).
    #[arg(long, default_value = "renders")]
    pub output: PathBuf,
    /// Renders allowed to run at the same time; more are refused with 429.
    #[arg(long, default_value_t = 2)]
    pub max_jobs: usize,
    /// Largest width or height accepted.
    #[arg(long, default_value_t = 4096)]
    pub max_size: u32,
    /// Largest samples per pixel accepted.
    #[arg(long, default_value_t = 16384)]
    pub max_spp: u32,
    /// Worker threads per render (default: all cores).
    #[arg(long)]
    pub threads: Option<usize>,
}

#[derive(Debug, thiserror::Error)]
pub enum ServeError {
    #[error("{path}: {message}")]
    Folder { path: String, message: String },
    #[error("invalid option: {0}")]
    Option(String),
    #[error("cannot listen on {addr}: {message}")]
    Bind { addr: String, message: String },
}

struct AppState {
    policy: Policy,
    jobs: Jobs,
    /// Whether the server listens on loopback only; then the Host header must name loopback too
    /// (a DNS-rebinding page cannot reach the API).
    loopback: bool,
}

type Shared = Arc<AppState>;

impl ServeArgs {
    /// Checks the options and canonicalises the folders.
    pub fn policy(&self) -> Result<Policy, ServeError> {
        if self.max_jobs == 0 || self.max_jobs > 64 {
            return Err(ServeError::Option("--max-jobs must be 1 to 64".into()));
        }
        if self.max_size == 0 || self.max_size > trayecto::render::MAX_DIMENSION {
            return Err(ServeError::Option(format!(
                "--max-size must be 1 to {}",
                trayecto::render::MAX_DIMENSION
            )));
        }
        if self.max_spp == 0 || self.max_spp > trayecto::render::MAX_SPP {
            return Err(ServeError::Option(format!(
                "--max-spp must be 1 to {}",
                trayecto::render::MAX_SPP
            )));
        }
        if let Some(t) = self.threads
            && (t == 0 || t > 1024)
        {
            return Err(ServeError::Option("--threads must be 1 to 1024".into()));
        }
        let folder = |p: &PathBuf, m: String| ServeError::Folder {
            path: p.display().to_string(),
            message: m,
        };
        let scenes_dir = match &self.scenes {
            None => None,
            Some(p) => {
                let c = p
                    .canonicalize()
                    .map_err(|e| folder(p, format!("scenes folder: {e}")))?;
                if !c.is_dir() {
                    return Err(folder(p, "the scenes folder is not a folder".into()));
                }
                Some(c)
            }
        };
        std::fs::create_dir_all(&self.output)
            .map_err(|e| folder(&self.output, format!("output folder: {e}")))?;
        let output_dir = self
            .output
            .canonicalize()
            .map_err(|e| folder(&self.output, format!("output folder: {e}")))?;
        Ok(Policy {
            scenes_dir,
            output_dir,
            limits: Limits {
                max_size: self.max_size,
                max_spp: self.max_spp,
                max_jobs: self.max_jobs,
                ..Limits::default()
            },
            threads: self.threads,
        })
    }
}

/// The router for a policy (exposed so it can be served by other means).
pub fn router(policy: Policy, loopback: bool) -> Router {
    let state = Arc::new(AppState {
        jobs: Jobs::new(policy.limits.max_jobs, HISTORY, policy.output_dir.clone()),
        policy,
        loopback,
    });
    Router::new()
        .route(
            "/",
            get(|| async { asset(INDEX_HTML, "text/html; charset=utf-8") }),
        )
        .route(
            "/app.js",
            get(|| async { asset(APP_JS, "text/javascript; charset=utf-8") }),
        )
        .route(
            "/style.css",
            get(|| async { asset(STYLE_CSS, "text/css; charset=utf-8") }),
        )
        .route("/api/options", get(options))
        .route("/api/scenes", get(scenes))
        .route("/api/scene-defaults", get(scene_defaults))
        .route("/api/renders", get(list_renders).post(create_render))
        .route("/api/renders/{id}", get(render_status))
        .route("/api/renders/{id}/cancel", post(cancel_render))
        .route("/api/renders/{id}/preview.png", get(preview))
        .route("/api/renders/{id}/{file}", get(download))
        .fallback(|| async { error(StatusCode::NOT_FOUND, "no such page or API endpoint") })
        .layer(middleware::from_fn_with_state(state.clone(), guard))
        .with_state(state)
}

/// Starts listening (address printed once bound) and serves until the process ends.
pub fn run(args: &ServeArgs) -> anyhow::Result<()> {
    let policy = args.policy()?;
    let ip: std::net::IpAddr = args
        .host
        .parse()
        .map_err(|_| ServeError::Option(format!("--host '{}' is not an IP address", args.host)))?;
    let addr = SocketAddr::new(ip, args.port);
    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_io()
        .build()?;
    rt.block_on(async move {
        let listener = tokio::net::TcpListener::bind(addr)
            .await
            .map_err(|e| ServeError::Bind {
                addr: addr.to_string(),
                message: e.to_string(),
            })?;
        let local = listener.local_addr()?;
        // Written without println!: a closed stdout (a parent that read only the address) must
        // not bring the server down.
        use std::io::Write;
        let mut out = std::io::stdout();
        let scenes = policy
            .scenes_dir
            .as_ref()
            .map(|p| p.display().to_string())
            .unwrap_or_else(|| "built-in only (use --scenes DIR)".into());
        let _ = writeln!(out, "trayecto serve: listening on http://{local}/");
        let _ = writeln!(out, "scenes: {scenes}");
        let _ = writeln!(out, "output: {}", policy.output_dir.display());
        let _ = out.flush();
        axum::serve(listener, router(policy, ip.is_loopback())).await?;
        Ok(())
    })
}

fn asset(body: &'static str, content_type: &'static str) -> Response {
    ([(header::CONTENT_TYPE, content_type)], body).into_response()
}

fn json_response(status: StatusCode, v: Value) -> Response {
    (
        status,
        [(header::CONTENT_TYPE, "application/json")],
        v.to_string(),
    )
        .into_response()
}

fn error(status: StatusCode, message: impl Into<String>) -> Response {
    json_response(status, json!({ "error": message.into() }))
}

/// Host check (against DNS rebinding), cross-origin write check (against CSRF from other pages),
/// and security headers on every response.
async fn guard(State(st): State<Shared>, req: Request, next: Next) -> Response {
    let headers = req.headers();
    let host = headers
        .get(header::HOST)
        .and_then(|h| h.to_str().ok())
        .unwrap_or("");
    if st.loopback && !is_loopback_host(host) {
        return error(
            StatusCode::FORBIDDEN,
            "this server only answers to localhost",
        );
    }
    if req.method() != Method::GET
        && req.method() != Method::HEAD
        && let Some(origin) = headers.get(header::ORIGIN).and_then(|o| o.to_str().ok())
        && origin.strip_prefix("http://") != Some(host)
    {
        return error(StatusCode::FORBIDDEN, "cross-origin requests are refused");
    }
    let mut res = next.run(req).await;
    let h = res.headers_mut();
    h.insert(
        header::X_CONTENT_TYPE_OPTIONS,
        HeaderValue::from_static("nosniff"),
    );
    h.insert(
        header::CONTENT_SECURITY_POLICY,
        HeaderValue::from_static("default-src 'self'; img-src 'self' blob: data:"),
    );
    h.insert(header::CACHE_CONTROL, HeaderValue::from_static("no-store"));
    res
}

fn is_loopback_host(host: &str) -> bool {
    let name = if let Some(rest) = host.strip_prefix('[') {
        rest.split(']').next().unwrap_or("")
    } else {
        host.rsplit_once(':').map(|(h, _)| h).unwrap_or(host)
    };
    name.eq_ignore_ascii_case("localhost")
        || name
            .parse::<std::net::IpAddr>()
            .map(|ip| ip.is_loopback())
            .unwrap_or(false)
}

async fn options(State(st): State<Shared>) -> Response {
    use request::Defaults as D;
    let l = &st.policy.limits;
    json_response(
        StatusCode::OK,
        json!({
            "limits": {
                "max_size": l.max_size,
                "max_spp": l.max_spp,
                "max_secondary": l.max_secondary,
                "max_depth": l.max_depth,
                "max_samples": l.max_samples,
                "max_jobs": l.max_jobs,
                "max_body": l.max_body,
                "max_output_name": request::MAX_OUTPUT_NAME,
            },
            "defaults": {
                "scene": trayecto::scene::builtin::NAMES.first(),
                "output": D::OUTPUT,
                "width": D::WIDTH,
                "height": D::HEIGHT,
                "spp": D::SPP,
                "secondary": D::SECONDARY,
                "max_depth": D::MAX_DEPTH,
                "exposure": D::EXPOSURE,
                "integrator": "path",
                "tonemap": "clamp",
                "default_light": "",
            },
            "integrators": request::integrator_names(),
            "tonemaps": request::tonemap_names(),
            "default_lights": request::DEFAULT_LIGHT_NAMES,
        }),
    )
}

/// `?all=true` also lists the meshes another scene file under the folder refers to.
async fn scenes(
    State(st): State<Shared>,
    Query(q): Query<std::collections::HashMap<String, String>>,
) -> Response {
    let all = q
        .get("all")
        .is_some_and(|v| matches!(v.as_str(), "true" | "1" | "on" | "yes"));
    let dir = st.policy.scenes_dir.clone();
    let (files, hidden) = match dir {
        Some(d) => tokio::task::spawn_blocking(move || request::scene_list(&d, all))
            .await
            .unwrap_or_default(),
        None => (Vec::new(), 0),
    };
    json_response(
        StatusCode::OK,
        json!({ "builtin": trayecto::scene::builtin::NAMES, "files": files, "hidden": hidden }),
    )
}

/// `?scene=NAME`: the size, samples and depth a render of NAME gets from the file (the page
/// prefills them).
async fn scene_defaults(
    State(st): State<Shared>,
    Query(q): Query<std::collections::HashMap<String, String>>,
) -> Response {
    let Some(name) = q.get("scene").cloned() else {
        return error(StatusCode::BAD_REQUEST, "give ?scene=NAME");
    };
    if name.len() > request::MAX_SCENE_NAME {
        return error(StatusCode::BAD_REQUEST, "the scene name is too long");
    }
    let policy = st.policy.clone();
    match tokio::task::spawn_blocking(move || request::scene_defaults(&name, &policy)).await {
        Ok(Ok(v)) => json_response(StatusCode::OK, v),
        Ok(Err(m)) => error(StatusCode::BAD_REQUEST, m),
        Err(_) => error(StatusCode::INTERNAL_SERVER_ERROR, "internal error"),
    }
}

async fn list_renders(State(st): State<Shared>) -> Response {
    let list: Vec<Value> = st.jobs.all().iter().map(|j| j.to_json()).collect();
    json_response(
        StatusCode::OK,
        json!({ "renders": list, "active": st.jobs.active_count() }),
    )
}

/// Reads a request body of at most `limit` bytes. A declared length over the limit is refused
/// from the header alone; an undeclared (chunked) body that grows over it is read on, up to
/// [`DRAIN_MAX`], and dropped, so the client gets the 413 instead of a reset connection.
async fn read_limited(
    headers: &HeaderMap,
    mut body: Body,
    limit: usize,
) -> Result<Vec<u8>, Response> {
    let too_large = || {
        error(
            StatusCode::PAYLOAD_TOO_LARGE,
            format!("the request body is larger than {limit} bytes"),
        )
    };
    let declared = headers
        .get(header::CONTENT_LENGTH)
        .and_then(|v| v.to_str().ok())
        .and_then(|v| v.trim().parse::<u64>().ok());
    if declared.is_some_and(|n| n > limit as u64) {
        return Err(too_large());
    }
    let mut buf = Vec::new();
    let mut over = 0usize;
    while let Some(frame) = body.frame().await {
        let Ok(frame) = frame else {
            return Err(error(
                StatusCode::BAD_REQUEST,
                "could not read the request body",
            ));
        };
        let Ok(data) = frame.into_data() else {
            continue;
        };
        if over > 0 || buf.len() + data.len() > limit {
            over += data.len();
            if over > DRAIN_MAX {
                break;
            }
        } else {
            buf.extend_from_slice(&data);
        }
    }
    if over > 0 {
        return Err(too_large());
    }
    Ok(buf)
}

async fn create_render(State(st): State<Shared>, headers: HeaderMap, body: Body) -> Response {
    // Requiring JSON also makes a cross-site form post impossible (it cannot set this type).
    let is_json = headers
        .get(header::CONTENT_TYPE)
        .and_then(|v| v.to_str().ok())
        .map(|v| v.trim_start().starts_with("application/json"))
        .unwrap_or(false);
    if !is_json {
        return error(
            StatusCode::UNSUPPORTED_MEDIA_TYPE,
            "send the render request as JSON (Content-Type: application/json)",
        );
    }
    let body = match read_limited(&headers, body, st.policy.limits.max_body).await {
        Ok(b) => b,
        Err(r) => return r,
    };
    let policy = st.policy.clone();
    // Resolving a scene touches the file system: keep it off the async workers.
    let parsed = tokio::task::spawn_blocking(move || request::parse_request(&body, &policy)).await;
    let req = match parsed {
        Ok(Ok(r)) => r,
        Ok(Err(RequestError::Malformed(m))) => return error(StatusCode::BAD_REQUEST, m),
        Ok(Err(RequestError::Fields(f))) => {
            return json_response(
                StatusCode::BAD_REQUEST,
                json!({ "error": "some fields are invalid", "fields": f }),
            );
        }
        Err(_) => return error(StatusCode::INTERNAL_SERVER_ERROR, "internal error"),
    };
    match st.jobs.submit(req) {
        Ok(job) => json_response(StatusCode::CREATED, job.to_json()),
        Err(SubmitError::Busy(n)) => error(
            StatusCode::TOO_MANY_REQUESTS,
            format!("{n} renders are already running; wait for one to finish or cancel one"),
        ),
        Err(SubmitError::NameInUse(n)) => json_response(
            StatusCode::CONFLICT,
            json!({
                "error": "a running render writes this output name",
                "fields": { "output": format!("'{n}' is being written by a running render") }
            }),
        ),
        Err(SubmitError::NameTaken(n)) => json_response(
            StatusCode::CONFLICT,
            json!({
                "error": "an earlier render wrote this output name",
                "fields": {
                    "output": format!("'{n}' already exists in the output folder (files are never overwritten): choose another name")
                }
            }),
        ),
    }
}

fn find_job(st: &AppState, id: &str) -> Result<Arc<jobs::Job>, Response> {
    id.parse::<u64>()
        .ok()
        .and_then(|id| st.jobs.get(id))
        .ok_or_else(|| error(StatusCode::NOT_FOUND, "no such render"))
}

async fn render_status(State(st): State<Shared>, UrlPath(id): UrlPath<String>) -> Response {
    match find_job(&st, &id) {
        Ok(j) => json_response(StatusCode::OK, j.to_json()),
        Err(r) => r,
    }
}

async fn cancel_render(State(st): State<Shared>, UrlPath(id): UrlPath<String>) -> Response {
    let job = match find_job(&st, &id) {
        Ok(j) => j,
        Err(r) => return r,
    };
    job.cancel.store(true, std::sync::atomic::Ordering::Relaxed);
    json_response(StatusCode::OK, job.to_json())
}

async fn preview(State(st): State<Shared>, UrlPath(id): UrlPath<String>) -> Response {
    let job = match find_job(&st, &id) {
        Ok(j) => j,
        Err(r) => return r,
    };
    match tokio::task::spawn_blocking(move || job.preview_png()).await {
        Ok(Some(png)) => (
            [(header::CONTENT_TYPE, "image/png")],
            Body::from(png.as_ref().clone()),
        )
            .into_response(),
        _ => error(StatusCode::NOT_FOUND, "no preview (yet, or any more)"),
    }
}

async fn download(
    State(st): State<Shared>,
    UrlPath((id, file)): UrlPath<(String, String)>,
) -> Response {
    let job = match find_job(&st, &id) {
        Ok(j) => j,
        Err(r) => return r,
    };
    let (path, mime, ext) = {
        let s = job.status();
        match file.as_str() {
            "image.png" => (s.png.clone(), "image/png", "png"),
            "image.exr" => (s.exr.clone(), "image/x-exr", "exr"),
            _ => return error(StatusCode::NOT_FOUND, "no such file"),
        }
    };
    let Some(path) = path else {
        return error(StatusCode::NOT_FOUND, "the render has not finished");
    };
    // The path was built by the server from a sanitised name inside the output folder.
    match tokio::task::spawn_blocking(move || std::fs::read(path)).await {
        Ok(Ok(bytes)) => (
            [
                (header::CONTENT_TYPE, mime.to_string()),
                (
                    header::CONTENT_DISPOSITION,
                    format!("attachment; filename=\"{}.{ext}\"", job.request.output),
                ),
            ],
            Body::from(bytes),
        )
            .into_response(),
        _ => error(
            StatusCode::GONE,
            "the file is no longer in the output folder",
        ),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn loopback_hosts() {
        for ok in [
            "127.0.0.1:8080",
            "localhost:1",
            "LOCALHOST",
            "[::1]:80",
            "127.0.0.2",
        ] {
            assert!(is_loopback_host(ok), "{ok}");
        }
        for bad in ["evil.com", "evil.com:8080", "10.0.0.1:80", "", "[::2]:80"] {
            assert!(!is_loopback_host(bad), "{bad}");
        }
    }
}
