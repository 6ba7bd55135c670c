//! The view's HTTP server on 127.0.0.1 ([`tiny_http`]: small and synchronous, four small
//! dependencies and no async runtime — a few seconds of build on two cores, where hyper/axum
//! bring tokio).
//!
//! Routes (the only ones; a request's path is matched, never mapped to a file):
//! - `GET /`: the page (`page.html`, inside the binary);
//! - `GET /events`: server-sent events (`text/event-stream`), the state first;
//! - `GET /state.json`: the state;
//! - `GET /frame.png?g=GEN&f=FRAME&level=preview|final&layer=LAYER&ev=STOPS`: a picture, rendered
//!   on demand and cached ([`super::layers::Layer`] names the layers);
//! - `GET /stats.json?g=GEN`: the frames' statistics so far;
//! - `POST /render-shot`: render the shot into its output folder.
//!
//! Refused: a `Host` other than `127.0.0.1:PORT` or `localhost:PORT` (403: a page elsewhere
//! that rebinds its name to 127.0.0.1 sends its own name), a `POST` whose `Origin` is another
//! site's (403), any other path (404), any other method (405).

use std::io::Write;
use std::sync::Arc;
use std::time::Duration;

use serde_json::json;
use tiny_http::{Header, Method, Request, Response};

use super::layers::Layer;
use super::session::{Level, Session};

/// The page, shipped inside the binary.
const PAGE: &str = include_str!("page.html");

/// The page's content policy: its own inline script and style, pictures and events from
/// this server only.
const CSP: &str = "default-src 'none'; script-src 'unsafe-inline'; style-src 'unsafe-inline'; \
                   img-src 'self'; connect-src 'self'; base-uri 'none'; form-action 'none'";

/// A bound server and its port.
pub struct Bound {
    server: tiny_http::Server,
    /// The port it listens on (127.0.0.1).
    pub port: u16,
}

/// Bind 127.0.0.1:`port` (0: a free port).
pub fn bind(port: u16) -> anyhow::Result<Bound> {
    let server = tiny_http::Server::http(("127.0.0.1", port))
        .map_err(|e| anyhow::anyhow!("cannot listen on 127.0.0.1:{port}: {e}"))?;
    let port = server
        .server_addr()
        .to_ip()
        .map(|a| a.port())
        .ok_or_else(|| anyhow::anyhow!("the server has no IP address"))?;
    Ok(Bound { server, port })
}

impl Bound {
    /// Serve requests, each on a thread of its own (a picture being rendered, or the event
    /// stream, holds its request), until the process ends.
    pub fn run(self, session: Arc<Session>) {
        let port = self.port;
        for request in self.server.incoming_requests() {
            let session = session.clone();
            std::thread::spawn(move || handle(&session, port, request));
        }
    }
}

fn header(value: &str, name: &str) -> Header {
    Header::from_bytes(name.as_bytes(), value.as_bytes()).expect("a valid header")
}

/// The value of the request's header `name`, if it has one.
fn header_value<'r>(request: &'r Request, name: &str) -> Option<&'r str> {
    request
        .headers()
        .iter()
        .find(|h| h.field.as_str().as_str().eq_ignore_ascii_case(name))
        .map(|h| h.value.as_str())
}

/// True when `host` (a `Host` header) is this server's loopback name and port.
pub fn host_allowed(host: Option<&str>, port: u16) -> bool {
    host.is_some_and(|h| {
        let h = h.to_ascii_lowercase();
        h == format!("127.0.0.1:{port}") || h == format!("localhost:{port}")
    })
}

/// True when `origin` (an `Origin` header) is absent or this server's own.
pub fn origin_allowed(origin: Option<&str>, port: u16) -> bool {
    origin.is_none_or(|o| {
        let o = o.to_ascii_lowercase();
        o == format!("http://127.0.0.1:{port}") || o == format!("http://localhost:{port}")
    })
}

fn text(status: u16, body: &str) -> Response<std::io::Cursor<Vec<u8>>> {
    Response::from_string(body)
        .with_status_code(status)
        .with_header(header("text/plain; charset=utf-8", "Content-Type"))
}

fn json_response(value: &serde_json::Value) -> Response<std::io::Cursor<Vec<u8>>> {
    Response::from_string(value.to_string())
        .with_header(header("application/json", "Content-Type"))
        .with_header(header("no-store", "Cache-Control"))
}

/// The query's value of `key` (the page writes plain values: no escapes to decode).
fn query<'u>(q: &'u str, key: &str) -> Option<&'u str> {
    q.split('&')
        .filter_map(|kv| kv.split_once('='))
        .find(|(k, _)| *k == key)
        .map(|(_, v)| v)
}

fn handle(session: &Arc<Session>, port: u16, request: Request) {
    if !host_allowed(header_value(&request, "Host"), port) {
        let _ = request.respond(text(
            403,
            "forbidden: this page answers only to its loopback address\n",
        ));
        return;
    }
    let url = request.url().to_string();
    let (path, q) = url.split_once('?').unwrap_or((&url, ""));
    let method = request.method().clone();
    let get = matches!(method, Method::Get | Method::Head);
    let response = match (path, get) {
        ("/", true) => Response::from_string(PAGE)
            .with_header(header("text/html; charset=utf-8", "Content-Type"))
            .with_header(header("no-store", "Cache-Control"))
            .with_header(header(CSP, "Content-Security-Policy")),
        ("/events", true) => return events(session, request),
        ("/state.json", true) => json_response(&session.snapshot()),
        ("/stats.json", true) => {
            match query(q, "g")
                .and_then(|g| g.parse().ok())
                .and_then(|g| session.generation(g))
            {
                Some(g) => json_response(&json!({"generation": g.id, "stats": g.stats()})),
                None => text(404, "no such generation\n"),
            }
        }
        ("/frame.png", true) => return picture(session, request, q),
        ("/render-shot", false) if method == Method::Post => {
            if !origin_allowed(header_value(&request, "Origin"), port) {
                text(403, "forbidden: another site's request\n")
            } else {
                match session.render_shot() {
                    Ok(()) => json_response(&json!({"started": true})),
                    Err(e) => text(409, &format!("{e}\n")),
                }
            }
        }
        ("/" | "/events" | "/state.json" | "/stats.json" | "/frame.png" | "/render-shot", _) => {
            text(405, "method not allowed\n")
        }
        _ => text(404, "not found\n"),
    };
    let response = response
        .with_header(header("nosniff", "X-Content-Type-Options"))
        .with_header(header("no-referrer", "Referrer-Policy"));
    let _ = request.respond(response);
}

/// `GET /frame.png`: the picture, rendered now if it is not cached.
fn picture(session: &Arc<Session>, request: Request, q: &str) {
    let parsed = (|| {
        let g: u64 = query(q, "g")?.parse().ok()?;
        let f: u32 = query(q, "f")?.parse().ok()?;
        let level = Level::parse(query(q, "level").unwrap_or("preview"))?;
        let layer = Layer::parse(query(q, "layer").unwrap_or("beauty"))?;
        let ev: f32 = query(q, "ev").unwrap_or("0").parse().ok()?;
        (ev.is_finite() && ev.abs() <= 20.0).then_some((g, f, level, layer, ev))
    })();
    let Some((g, f, level, layer, ev)) = parsed else {
        let _ = request.respond(text(400, "bad picture request\n"));
        return;
    };
    let Some(generation) = session.generation(g) else {
        let _ = request.respond(text(404, "no such generation (the scene changed since)\n"));
        return;
    };
    let rendered = match session.frame(&generation, f, level, layer.needs_passes()) {
        Ok(r) => r,
        Err(e) => {
            let _ = request.respond(text(500, &format!("{e}\n")));
            return;
        }
    };
    match rendered.png(layer, ev) {
        Ok(png) => {
            let response = Response::from_data(png.as_slice())
                .with_header(header("image/png", "Content-Type"))
                .with_header(header("private, max-age=3600", "Cache-Control"))
                .with_header(header(
                    &format!("{:.4}", rendered.seconds),
                    "X-Render-Seconds",
                ))
                .with_header(header("nosniff", "X-Content-Type-Options"));
            let _ = request.respond(response);
        }
        Err(e) => {
            let _ = request.respond(text(500, &format!("{e}\n")));
            return;
        }
    }
    if level == Level::Preview && !layer.needs_passes() {
        session.add_stats(&generation, f, &rendered);
    }
}

/// `GET /events`: the state, then every event, as server-sent events; a comment every 15 s
/// keeps the connection open. (The stream is written on the raw connection: tiny_http's
/// chunked bodies hold 8 KiB before they send, which would hold the events back.)
fn events(session: &Arc<Session>, request: Request) {
    let events = session.hub.subscribe();
    let head = Response::empty(200)
        .with_header(header("text/event-stream", "Content-Type"))
        .with_header(header("no-store", "Cache-Control"));
    let mut stream = request.upgrade("sse", head);
    let first = session.snapshot().to_string();
    if write!(stream, "data: {first}\n\n")
        .and_then(|_| stream.flush())
        .is_err()
    {
        return;
    }
    loop {
        let sent = match events.recv_timeout(Duration::from_secs(15)) {
            Ok(e) => write!(stream, "data: {e}\n\n"),
            Err(std::sync::mpsc::RecvTimeoutError::Timeout) => write!(stream, ": alive\n\n"),
            Err(_) => return,
        };
        if sent.and_then(|_| stream.flush()).is_err() {
            return;
        }
    }
}
