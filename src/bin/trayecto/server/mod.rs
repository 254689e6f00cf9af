//! `trayecto serve`: the thesis's GUI (§5.5, Annex B) as a web page with a progressive preview
//! (docs/DESIGN.md §2, web UI). An axum server on 127.0.0.1 by default serves the embedded page and a small
//! JSON API (documented in docs/src/web-ui.md); renders run on their own threads ([`jobs`]) and every
//! request is checked before any work starts ([`request`]).
//!
//! The server never reads a path taken from a URL: static files are embedded, downloads are looked
//! up by job id, and scene names are resolved only inside the canonical scenes folder.

// Handlers return an early `Response` as the error of small helpers; its size does not matter
// once per HTTP request.
#![allow(clippy::result_large_err)]

pub mod jobs;
pub mod viewport;
// The request and upload checks live in the library, where the fuzz targets reach them.
pub use trayecto::server::{folder, request, upload};

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
    /// Renders allowed to run at the same time; more wait in a queue.
    #[arg(long, default_value_t = 2)]
    pub max_jobs: usize,
    /// Renders allowed to wait for a free slot; more are refused with 429.
    #[arg(long, default_value_t = 16)]
    pub max_queue: usize,
    /// Largest width or height accepted.
    #[arg(long, default_value_t = 4096)]
    pub max_size: u32,
    /// Largest samples per pixel accepted.
    #[arg(long, default_value_t = 16384)]
    pub max_spp: u32,
    /// Largest upload accepted (a .glb or a .zip), in MiB.
    #[arg(long, default_value_t = 128, value_name = "MIB")]
    pub max_upload: u64,
    /// Largest total size an uploaded .zip may unpack to, in MiB.
    #[arg(long, default_value_t = 1024, value_name = "MIB")]
    pub max_unpacked: u64,
    /// Most memory one render's scene load may take (e.g. 2G); a file that asks for more fails
    /// its job with an error naming it. Default: the total.
    #[arg(long, value_name = "SIZE", value_parser = trayecto::limits::parse_size)]
    pub memory_limit: Option<u64>,
    /// Most memory all renders and scene views load together. Default: half the physical
    /// memory (or of `ulimit -v`).
    #[arg(long, value_name = "SIZE", value_parser = trayecto::limits::parse_size)]
    pub memory_total: Option<u64>,
    /// Worker threads per render (default: all cores).
    #[arg(long)]
    pub threads: Option<usize>,
    /// Access token the page and the API require (16 to 256 letters, digits, '-', '_', '.');
    /// on any address but 127.0.0.1 and ::1 one is generated and printed when not given.
    #[arg(long, value_name = "TOKEN")]
    pub token: Option<String>,
    /// Serve without a token: only allowed on 127.0.0.1 and ::1.
    #[arg(long, conflicts_with = "token")]
    pub no_token: bool,
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
    /// The access token every request must carry, if any ([`Access`]).
    access: Option<Access>,
    /// The pages' interactive previews (outside the render queue, [`viewport`]).
    viewports: viewport::Viewports,
}

/// Access by token, as Jupyter does: the start-up line prints `/?token=T`; opening
/// it stores the token in a cookie (HttpOnly, SameSite=Strict, so other sites' pages cannot use
/// it) and redirects to the bare page; API clients send `Authorization: Bearer T` instead.
#[derive(Clone, Debug)]
pub struct Access {
    pub token: String,
    /// Cookies are per host, not per port: the name carries the port so that two servers on
    /// one machine keep their own tokens.
    pub cookie: String,
}

impl Access {
    pub fn new(token: String, port: u16) -> Access {
        Access {
            token,
            cookie: format!("trayecto_token_{port}"),
        }
    }
}

/// The addresses served without a token: this machine's default loopback addresses. Every other
/// address, other 127.x.y.z ones included, needs a token (`--no-token` is refused there).
pub fn token_free(ip: std::net::IpAddr) -> bool {
    ip == std::net::IpAddr::from(std::net::Ipv4Addr::LOCALHOST)
        || ip == std::net::IpAddr::from(std::net::Ipv6Addr::LOCALHOST)
}

/// Comparison whose time does not depend on where the strings differ.
fn same_secret(a: &[u8], b: &[u8]) -> bool {
    a.len() == b.len() && a.iter().zip(b).fold(0u8, |acc, (x, y)| acc | (x ^ y)) == 0
}

/// 128 random bits from the operating system, as 32 hexadecimal digits.
fn generate_token() -> Result<String, ServeError> {
    use std::io::Read;
    let mut bytes = [0u8; 16];
    std::fs::File::open("/dev/urandom")
        .and_then(|mut f| f.read_exact(&mut bytes))
        .map_err(|e| {
            ServeError::Option(format!(
                "cannot generate an access token ({e}): give one with --token"
            ))
        })?;
    Ok(bytes.iter().map(|b| format!("{b:02x}")).collect())
}

type Shared = Arc<AppState>;

impl ServeArgs {
    /// The access token for serving on `ip`: the given one, a generated one on addresses other
    /// than 127.0.0.1 and ::1, or none there. `--no-token` elsewhere is refused.
    pub fn access_token(&self, ip: std::net::IpAddr) -> Result<Option<String>, ServeError> {
        if let Some(t) = &self.token {
            let ok = (16..=256).contains(&t.len())
                && t.chars()
                    .all(|c| c.is_ascii_alphanumeric() || matches!(c, '-' | '_' | '.'));
            if !ok {
                return Err(ServeError::Option(
                    "--token must be 16 to 256 letters, digits, '-', '_' or '.'".into(),
                ));
            }
            return Ok(Some(t.clone()));
        }
        match (token_free(ip), self.no_token) {
            (true, _) => Ok(None),
            (false, true) => Err(ServeError::Option(format!(
                "refusing to serve on {ip} without a token: anyone who can reach it could start \
                 renders (drop --no-token to get a generated token, or give --token)"
            ))),
            (false, false) => generate_token().map(Some),
        }
    }

    /// Checks the options and canonicalises the folders.
    pub fn policy(&self) -> Result<Policy, ServeError> {
        if self.max_jobs == 0 || self.max_jobs > 64 {
            return Err(ServeError::Option("--max-jobs must be 1 to 64".into()));
        }
        if self.max_upload == 0 || self.max_upload > 4096 {
            return Err(ServeError::Option(
                "--max-upload must be 1 to 4096 (MiB)".into(),
            ));
        }
        if self.max_unpacked == 0 || self.max_unpacked > 65536 {
            return Err(ServeError::Option(
                "--max-unpacked must be 1 to 65536 (MiB)".into(),
            ));
        }
        if self.max_queue > 1024 {
            return Err(ServeError::Option("--max-queue must be 0 to 1024".into()));
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
        let total = self
            .memory_total
            .unwrap_or_else(trayecto::limits::default_limit);
        Ok(Policy {
            scenes_dir,
            output_dir,
            limits: Limits {
                max_size: self.max_size,
                max_spp: self.max_spp,
                max_jobs: self.max_jobs,
                max_queue: self.max_queue,
                upload: upload::UploadLimits {
                    max_file: (self.max_upload << 20) as usize,
                    max_unpacked: self.max_unpacked << 20,
                    ..Default::default()
                },
                memory_total: total,
                memory_per_job: self.memory_limit.unwrap_or(total).min(total),
                ..Limits::default()
            },
            threads: self.threads,
        })
    }
}

/// The router for a policy (exposed so it can be served by other means).
pub fn router(policy: Policy, loopback: bool, access: Option<Access>) -> Router {
    let state = Arc::new(AppState {
        access,
        jobs: Jobs::new(
            policy.limits.max_jobs,
            policy.limits.max_queue,
            HISTORY,
            policy.output_dir.clone(),
        )
        .with_memory(policy.limits.memory_total, policy.limits.memory_per_job),
        policy,
        loopback,
        viewports: Default::default(),
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
        .route("/api/uploads", post(upload_scene))
        .route("/api/renders/{id}", get(render_status))
        .route("/api/renders/{id}/cancel", post(cancel_render))
        .route("/api/renders/{id}/preview.png", get(preview))
        .route("/api/renders/{id}/linear", get(render_linear))
        .route("/api/scene-view", get(scene_view))
        .route("/api/viewport", post(viewport_submit))
        .route("/api/viewport/{session}", get(viewport_status))
        .route("/api/viewport/{session}/linear", get(viewport_linear))
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
    let token = args.access_token(ip)?;
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
        if let Some(t) = &token {
            let _ = writeln!(
                out,
                "access token required; open the page at http://{local}/?token={t}"
            );
        }
        let _ = writeln!(out, "scenes: {scenes}");
        let _ = writeln!(out, "output: {}", policy.output_dir.display());
        let _ = out.flush();
        let access = token.map(|t| Access::new(t, local.port()));
        axum::serve(listener, router(policy, ip.is_loopback(), access)).await?;
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
    let mut res = admit(&st, req, next).await;
    let h = res.headers_mut();
    h.insert(
        header::X_CONTENT_TYPE_OPTIONS,
        HeaderValue::from_static("nosniff"),
    );
    // No other site may frame the page (clickjacking): CSP `frame-ancestors`, and
    // `X-Frame-Options` for browsers without it; no address (a job id, a token) leaks as Referer.
    h.insert(
        header::CONTENT_SECURITY_POLICY,
        HeaderValue::from_static(
            "default-src 'self'; img-src 'self' blob: data:; frame-ancestors 'none'",
        ),
    );
    h.insert(header::X_FRAME_OPTIONS, HeaderValue::from_static("DENY"));
    h.insert(
        header::REFERRER_POLICY,
        HeaderValue::from_static("no-referrer"),
    );
    h.insert(header::CACHE_CONTROL, HeaderValue::from_static("no-store"));
    res
}

/// The checks of [`guard`]: the handler's answer, or the refusal.
async fn admit(st: &AppState, req: Request, next: Next) -> Response {
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
    if let Some(access) = &st.access
        && let Some(refusal) = check_token(access, &req)
    {
        return refusal;
    }
    next.run(req).await
}

/// `None` when the request carries the token (a Bearer header, `X-Trayecto-Token` or the
/// cookie); otherwise the answer: a redirect that sets the cookie for `GET …?token=T`, else 401.
fn check_token(access: &Access, req: &Request) -> Option<Response> {
    let ok = |t: &str| same_secret(t.trim().as_bytes(), access.token.as_bytes());
    let headers = req.headers();
    // The scheme is case-insensitive (RFC 9110 §11.1): "bearer" is "Bearer".
    let header_ok = headers
        .get(header::AUTHORIZATION)
        .and_then(|v| v.to_str().ok())
        .and_then(|v| v.trim_start().split_once(' '))
        .filter(|(scheme, _)| scheme.eq_ignore_ascii_case("bearer"))
        .is_some_and(|(_, t)| ok(t))
        || headers
            .get("x-trayecto-token")
            .and_then(|v| v.to_str().ok())
            .is_some_and(ok);
    let cookie_ok = headers
        .get_all(header::COOKIE)
        .iter()
        .filter_map(|v| v.to_str().ok())
        .flat_map(|v| v.split(';'))
        .filter_map(|c| c.trim().split_once('='))
        .any(|(k, v)| k == access.cookie && ok(v));
    if header_ok || cookie_ok {
        return None;
    }
    let query_token = req.uri().query().and_then(|q| {
        q.split('&')
            .filter_map(|kv| kv.split_once('='))
            .find(|(k, _)| *k == "token")
            .map(|(_, v)| v)
    });
    if req.method() == Method::GET
        && let Some(t) = query_token
        && ok(t)
    {
        // The page is reloaded without the token in its address (so it does not stay in the
        // history or leak through Referer); the cookie carries it from now on.
        let cookie = format!(
            "{}={}; Path=/; HttpOnly; SameSite=Strict",
            access.cookie, access.token
        );
        return Some(
            (
                StatusCode::SEE_OTHER,
                [
                    (header::LOCATION, req.uri().path().to_string()),
                    (header::SET_COOKIE, cookie),
                ],
            )
                .into_response(),
        );
    }
    let message = if query_token.is_some() {
        "wrong access token: use the address with ?token= that the server printed when it started"
    } else {
        "this server needs its access token: open the address with ?token= that it printed when \
         it started (API clients: send Authorization: Bearer TOKEN)"
    };
    let mut res = if req.uri().path().starts_with("/api/") {
        error(StatusCode::UNAUTHORIZED, message)
    } else {
        (
            StatusCode::UNAUTHORIZED,
            [(header::CONTENT_TYPE, "text/plain; charset=utf-8")],
            format!("Trayecto: {message}\n"),
        )
            .into_response()
    };
    res.headers_mut().insert(
        header::WWW_AUTHENTICATE,
        HeaderValue::from_static("Bearer realm=\"trayecto\""),
    );
    Some(res)
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
                "max_queue": l.max_queue,
                "max_upload": l.upload.max_file,
                "max_unpacked": l.upload.max_unpacked,
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
                "tonemap": trayecto::film::tonemap::Tonemap::default().name(),
                "default_light": "",
            },
            "integrators": request::integrator_names(),
            "tonemaps": request::tonemap_names(),
            "default_lights": request::DEFAULT_LIGHT_NAMES,
            "uploads": st.policy.scenes_dir.is_some(),
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
    let (files, hidden, environments) = match dir {
        Some(d) => tokio::task::spawn_blocking(move || {
            let (f, h) = folder::scene_list(&d, all);
            (f, h, folder::list_environments(&d))
        })
        .await
        .unwrap_or_default(),
        None => (Vec::new(), 0, Vec::new()),
    };
    json_response(
        StatusCode::OK,
        json!({
            "builtin": trayecto::scene::builtin::NAMES,
            "files": files,
            "hidden": hidden,
            "environments": environments,
        }),
    )
}

/// The `scene` query parameter of `/api/scene-defaults` and `/api/scene-view`, or the 400 to send
/// when it is missing or longer than any scene name the request parser accepts.
fn scene_param(q: &std::collections::HashMap<String, String>) -> Result<String, Response> {
    let Some(name) = q.get("scene").cloned() else {
        return Err(error(StatusCode::BAD_REQUEST, "give ?scene=NAME"));
    };
    if name.len() > folder::MAX_SCENE_NAME {
        return Err(error(StatusCode::BAD_REQUEST, "the scene name is too long"));
    }
    Ok(name)
}

/// `?scene=NAME`: the size, samples and depth a render of NAME gets from the file (the page
/// prefills them).
async fn scene_defaults(
    State(st): State<Shared>,
    Query(q): Query<std::collections::HashMap<String, String>>,
) -> Response {
    let name = match scene_param(&q) {
        Ok(n) => n,
        Err(r) => return r,
    };
    let policy = st.policy.clone();
    let jobs = st.jobs.clone();
    // Reading a scene file is a load like a render's: it waits for a slot (jobs::Jobs::run_load).
    match tokio::task::spawn_blocking(move || {
        let builtin = matches!(
            request::scene_source(&name, &policy)?,
            request::SceneSource::Builtin(_)
        );
        jobs.run_load(builtin, || request::scene_defaults(&name, &policy))
    })
    .await
    {
        Ok(Ok(v)) => json_response(StatusCode::OK, v),
        Ok(Err(m)) => error(StatusCode::BAD_REQUEST, m),
        Err(_) => error(StatusCode::INTERNAL_SERVER_ERROR, "internal error"),
    }
}

async fn list_renders(State(st): State<Shared>) -> Response {
    let list: Vec<Value> = st.jobs.all().iter().map(|j| st.jobs.json(j)).collect();
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

/// The JSON render request of a POST (`what` names it in the 415 message): checked to be JSON,
/// read within the body limit, parsed and validated off the async workers. `Err` is the response
/// to send. Requiring JSON also makes a cross-site form post impossible (it cannot set this type).
async fn read_render_request(
    st: &Shared,
    headers: &HeaderMap,
    body: Body,
    what: &str,
) -> Result<request::RenderRequest, Response> {
    let is_json = headers
        .get(header::CONTENT_TYPE)
        .and_then(|v| v.to_str().ok())
        .map(|v| v.trim_start().starts_with("application/json"))
        .unwrap_or(false);
    if !is_json {
        return Err(error(
            StatusCode::UNSUPPORTED_MEDIA_TYPE,
            format!("send {what} as JSON (Content-Type: application/json)"),
        ));
    }
    let body = read_limited(headers, body, st.policy.limits.max_body).await?;
    let policy = st.policy.clone();
    // Resolving a scene touches the file system: keep it off the async workers.
    let parsed = tokio::task::spawn_blocking(move || request::parse_request(&body, &policy)).await;
    match parsed {
        Ok(Ok(r)) => Ok(r),
        Ok(Err(RequestError::Malformed(m))) => Err(error(StatusCode::BAD_REQUEST, m)),
        Ok(Err(RequestError::Fields(f))) => Err(json_response(
            StatusCode::BAD_REQUEST,
            json!({ "error": "some fields are invalid", "fields": f }),
        )),
        Err(_) => Err(error(StatusCode::INTERNAL_SERVER_ERROR, "internal error")),
    }
}

async fn create_render(State(st): State<Shared>, headers: HeaderMap, body: Body) -> Response {
    let req = match read_render_request(&st, &headers, body, "the render request").await {
        Ok(r) => r,
        Err(r) => return r,
    };
    match st.jobs.submit(req) {
        Ok(job) => json_response(StatusCode::CREATED, st.jobs.json(&job)),
        Err(SubmitError::Busy { running, queued }) => error(
            StatusCode::TOO_MANY_REQUESTS,
            format!(
                "the queue is full ({running} renders running, {queued} waiting): wait for one to finish or cancel one"
            ),
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

/// `POST /api/uploads?name=FILE.glb|FILE.zip` with the file as the body ([`upload`]). Only
/// binary content types are accepted: a cross-site form can send neither them nor the token.
async fn upload_scene(
    State(st): State<Shared>,
    Query(q): Query<std::collections::HashMap<String, String>>,
    headers: HeaderMap,
    body: Body,
) -> Response {
    let Some(scenes_dir) = st.policy.scenes_dir.clone() else {
        return error(
            StatusCode::BAD_REQUEST,
            "this server has no scenes folder to upload into (start it with --scenes DIR)",
        );
    };
    let binary = headers
        .get(header::CONTENT_TYPE)
        .and_then(|v| v.to_str().ok())
        .map(|v| {
            v.split(';')
                .next()
                .unwrap_or("")
                .trim()
                .to_ascii_lowercase()
        })
        .is_some_and(|t| {
            matches!(
                t.as_str(),
                "application/octet-stream"
                    | "application/zip"
                    | "application/x-zip-compressed"
                    | "model/gltf-binary"
            )
        });
    if !binary {
        return error(
            StatusCode::UNSUPPORTED_MEDIA_TYPE,
            "send the file itself as the body (Content-Type: application/octet-stream)",
        );
    }
    let Some(name) = q.get("name").cloned() else {
        return error(
            StatusCode::BAD_REQUEST,
            "give the file name: ?name=FILE.glb",
        );
    };
    let limits = st.policy.limits.upload.clone();
    let body = match read_limited(&headers, body, limits.max_file).await {
        Ok(b) => b,
        Err(r) => return r,
    };
    let stored =
        tokio::task::spawn_blocking(move || upload::store(&scenes_dir, &name, &body, &limits))
            .await;
    use upload::UploadError as E;
    match stored {
        Ok(Ok(s)) => json_response(
            StatusCode::CREATED,
            json!({ "scenes": s.scenes, "skipped": s.skipped }),
        ),
        Ok(Err(e)) => {
            let status = match &e {
                E::Invalid(_) => StatusCode::BAD_REQUEST,
                E::TooLarge(_) => StatusCode::PAYLOAD_TOO_LARGE,
                E::Exists(_) => StatusCode::CONFLICT,
                E::Io(_) => StatusCode::INTERNAL_SERVER_ERROR,
            };
            error(status, e.to_string())
        }
        Err(_) => error(StatusCode::INTERNAL_SERVER_ERROR, "internal error"),
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
        Ok(j) => json_response(StatusCode::OK, st.jobs.json(&j)),
        Err(r) => r,
    }
}

async fn cancel_render(State(st): State<Shared>, UrlPath(id): UrlPath<String>) -> Response {
    let job = match find_job(&st, &id) {
        Ok(j) => j,
        Err(r) => return r,
    };
    st.jobs.cancel(&job);
    json_response(StatusCode::OK, st.jobs.json(&job))
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
    // The file, its type and the name it downloads as.
    let out = &job.request.output;
    let (path, mime, name) = {
        let s = job.status();
        match file.as_str() {
            "image.png" => (s.png.clone(), "image/png", format!("{out}.png")),
            "image.exr" => (s.exr.clone(), "image/x-exr", format!("{out}.exr")),
            "denoised.png" => (
                s.denoised.clone().map(|d| d.0),
                "image/png",
                format!("{out}.denoised.png"),
            ),
            "denoised.exr" => (
                s.denoised.clone().map(|d| d.1),
                "image/x-exr",
                format!("{out}.denoised.exr"),
            ),
            // A sequence's frames as written (`frame-NNNN.png`/`.exr`), named as the sequence
            // names them, `<output>_NNNN.png`.
            f => match f
                .strip_prefix("frame-")
                .and_then(|f| f.split_once('.'))
                .and_then(|(n, ext)| Some((n.parse::<u32>().ok()?, ext)))
            {
                Some((n, ext @ ("png" | "exr"))) => {
                    let Some(done) = s.frames_done.iter().find(|d| d.frame == n) else {
                        return error(StatusCode::NOT_FOUND, "that frame has not been written");
                    };
                    let (file, mime) = if ext == "png" {
                        (&done.png, "image/png")
                    } else {
                        (&done.exr, "image/x-exr")
                    };
                    (Some(file.clone()), mime, format!("{out}_{n:04}.{ext}"))
                }
                _ => return error(StatusCode::NOT_FOUND, "no such file"),
            },
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
                    format!("attachment; filename=\"{name}\""),
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

/// Linear RGB as the page tone-maps it: little-endian f32 triples, rows top first; the size in
/// `X-Width`/`X-Height` headers.
fn linear_response(
    width: u32,
    height: u32,
    data: Vec<f32>,
    extra: &[(&'static str, String)],
) -> Response {
    let mut bytes = Vec::with_capacity(data.len() * 4);
    for v in data {
        // Non-finite values would poison the page's tone mapping; the library maps them to 0 too.
        bytes.extend_from_slice(&(if v.is_finite() { v } else { 0.0 }).to_le_bytes());
    }
    let mut res = (
        [
            (header::CONTENT_TYPE, "application/octet-stream".to_string()),
            (header::CACHE_CONTROL, "no-store".to_string()),
        ],
        Body::from(bytes),
    )
        .into_response();
    let h = res.headers_mut();
    for (k, v) in [
        ("x-width", width.to_string()),
        ("x-height", height.to_string()),
    ]
    .into_iter()
    .chain(extra.iter().map(|(k, v)| (*k, v.clone())))
    {
        if let Ok(v) = HeaderValue::from_str(&v) {
            h.insert(k, v);
        }
    }
    res
}

fn image_floats(image: &trayecto::film::Image) -> Vec<f32> {
    image.data.iter().flat_map(|p| p.to_array()).collect()
}

/// `?layer=beauty|albedo|normal|samples|variance|denoised`: a finished render's linear image (read back from its
/// EXR, which holds the film exactly as f32), or the preview of a running one (beauty only).
async fn render_linear(
    State(st): State<Shared>,
    UrlPath(id): UrlPath<String>,
    Query(q): Query<std::collections::HashMap<String, String>>,
) -> Response {
    let job = match find_job(&st, &id) {
        Ok(j) => j,
        Err(r) => return r,
    };
    let layer = q.get("layer").map(String::as_str).unwrap_or("beauty");
    let (exr, denoised, preview, version) = {
        let s = job.status();
        (
            s.exr.clone(),
            s.denoised.clone().map(|d| d.1),
            s.preview.clone(),
            s.preview_version,
        )
    };
    // The AOV layers served (when the request asked for them): the denoising guides and the
    // film's statistics; a one-channel layer is served as grey RGB like the others.
    let aov = matches!(layer, "albedo" | "normal" | "samples" | "variance")
        .then(|| trayecto::film::aov::AovKind::from_name(layer))
        .flatten()
        .filter(|kind| job.request.aovs.contains(kind));
    let (path, channels): (_, [&str; 3]) = match (layer, aov) {
        ("beauty", _) => (exr, ["R", "G", "B"]),
        ("denoised", _) => (denoised, ["R", "G", "B"]),
        (_, Some(kind)) => match *kind.channels() {
            [r, g, b] => (exr, [r, g, b]),
            [y] => (exr, [y; 3]),
            _ => unreachable!("AOV layers have one or three channels"),
        },
        _ => {
            return error(
                StatusCode::NOT_FOUND,
                "no such layer in this render (beauty; albedo, normal, samples and variance when asked for with aovs; denoised with denoise)",
            );
        }
    };
    let Some(path) = path else {
        if layer == "beauty"
            && let Some(img) = preview
        {
            let (w, h) = (img.width, img.height);
            let data = tokio::task::spawn_blocking(move || image_floats(&img))
                .await
                .unwrap_or_default();
            return linear_response(w, h, data, &[("x-version", version.to_string())]);
        }
        return error(StatusCode::NOT_FOUND, "the render has not finished");
    };
    let read = tokio::task::spawn_blocking(move || {
        let (w, h, chans) = trayecto::film::output::read_exr_channels(&path).ok()?;
        let pick: Vec<&Vec<f32>> = channels
            .iter()
            .map(|c| chans.iter().find(|(n, _)| n == c).map(|(_, v)| v))
            .collect::<Option<_>>()?;
        let n = (w * h) as usize;
        if pick.iter().any(|v| v.len() != n) {
            return None;
        }
        let data: Vec<f32> = (0..n)
            .flat_map(|i| pick.iter().map(move |v| v[i]))
            .collect();
        Some((w, h, data))
    })
    .await;
    match read {
        Ok(Some((w, h, data))) => linear_response(w, h, data, &[]),
        _ => error(
            StatusCode::GONE,
            "the image is no longer in the output folder",
        ),
    }
}

/// `?scene=NAME`: the scene's bounds and the camera it renders with (its first, or the framing
/// camera for a model without one), for the page to orbit around. Builds the scene.
async fn scene_view(
    State(st): State<Shared>,
    Query(q): Query<std::collections::HashMap<String, String>>,
) -> Response {
    let name = match scene_param(&q) {
        Ok(n) => n,
        Err(r) => return r,
    };
    let policy = st.policy.clone();
    let jobs = st.jobs.clone();
    // Loads and builds a scene file in a render slot, under the job memory budget: six pages
    // asking at once wait their turn instead of loading six times (jobs::Jobs::run_load).
    let built = tokio::task::spawn_blocking(move || {
        let source = request::scene_source(&name, &policy)?;
        let builtin = matches!(source, request::SceneSource::Builtin(_));
        let rename = |m: String| match &source {
            request::SceneSource::File(p) => m.replace(&*p.to_string_lossy(), &name),
            request::SceneSource::Builtin(_) => m,
        };
        jobs.run_load(builtin, || {
            let scene =
                trayecto::scene::load(&source.load_spec()).map_err(|e| rename(e.to_string()))?;
            let world = trayecto::world::World::build(scene, &Default::default())
                .map_err(|e| rename(e.to_string()))?;
            Ok::<_, String>(viewport::view_json(&world))
        })
    })
    .await;
    match built {
        Ok(Ok(v)) => json_response(StatusCode::OK, v),
        Ok(Err(m)) => error(StatusCode::BAD_REQUEST, m),
        Err(_) => error(StatusCode::INTERNAL_SERVER_ERROR, "internal error"),
    }
}

fn session_id(
    q: &std::collections::HashMap<String, String>,
    path: Option<&str>,
) -> Result<String, Response> {
    let id = path.or(q.get("session").map(String::as_str)).unwrap_or("");
    let ok = !id.is_empty()
        && id.len() <= viewport::MAX_SESSION_ID
        && id
            .bytes()
            .all(|b| b.is_ascii_alphanumeric() || b == b'-' || b == b'_');
    if ok {
        Ok(id.to_string())
    } else {
        Err(error(
            StatusCode::BAD_REQUEST,
            format!(
                "give the viewport session: ?session=ID (1 to {} letters, digits, '-', '_')",
                viewport::MAX_SESSION_ID
            ),
        ))
    }
}

/// `POST /api/viewport?session=ID` with a render request (its `camera`, size and `spp`; no
/// output is written): the session's preview restarts with this view at once.
async fn viewport_submit(
    State(st): State<Shared>,
    Query(q): Query<std::collections::HashMap<String, String>>,
    headers: HeaderMap,
    body: Body,
) -> Response {
    let id = match session_id(&q, None) {
        Ok(id) => id,
        Err(r) => return r,
    };
    let req = match read_render_request(&st, &headers, body, "the view").await {
        Ok(r) => r,
        Err(r) => return r,
    };
    match st.viewports.submit(&id, req, &st.jobs) {
        Ok(generation) => json_response(
            StatusCode::ACCEPTED,
            json!({ "session": id, "generation": generation }),
        ),
        Err(m) => error(StatusCode::SERVICE_UNAVAILABLE, m),
    }
}

async fn viewport_status(State(st): State<Shared>, UrlPath(session): UrlPath<String>) -> Response {
    let id = match session_id(&Default::default(), Some(&session)) {
        Ok(id) => id,
        Err(r) => return r,
    };
    match st.viewports.get(&id) {
        Some(s) => json_response(StatusCode::OK, s.json()),
        None => error(
            StatusCode::NOT_FOUND,
            "no such viewport session (send a view first)",
        ),
    }
}

async fn viewport_linear(State(st): State<Shared>, UrlPath(session): UrlPath<String>) -> Response {
    let id = match session_id(&Default::default(), Some(&session)) {
        Ok(id) => id,
        Err(r) => return r,
    };
    let Some((img, version, samples)) = st.viewports.get(&id).and_then(|s| s.image()) else {
        return error(StatusCode::NOT_FOUND, "no viewport image yet");
    };
    let (w, h) = (img.width, img.height);
    let data = tokio::task::spawn_blocking(move || image_floats(&img))
        .await
        .unwrap_or_default();
    linear_response(
        w,
        h,
        data,
        &[
            ("x-version", version.to_string()),
            ("x-samples", samples.to_string()),
        ],
    )
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
