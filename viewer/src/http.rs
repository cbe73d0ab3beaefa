//! The HTTP server: `tiny_http` (synchronous, no async runtime: every
//! request is short except renders, which a worker thread does), a few
//! request threads, bounded bodies, and a clean stop on request, on Ctrl-C
//! (by the caller) or when the run directory disappears.

use std::io::Read;
use std::net::SocketAddr;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::Duration;

use tiny_http::{Header, Response, Server};

use crate::ViewerError;
use crate::api::{MAX_BODY, Reply, handle};
use crate::jobs::Jobs;
use crate::state::Viewer;

/// Where and how to serve.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ServerOptions {
    /// Address to bind (`127.0.0.1`: this machine only).
    pub host: String,
    /// Port (0: any free port).
    pub port: u16,
    /// Threads answering requests.
    pub threads: usize,
}

impl Default for ServerOptions {
    fn default() -> Self {
        Self {
            host: "127.0.0.1".into(),
            port: 7007,
            threads: 4,
        }
    }
}

/// A running server.
pub struct ServerHandle {
    /// The bound address.
    pub addr: SocketAddr,
    stop: Arc<AtomicBool>,
    reason: Arc<Mutex<Option<String>>>,
    server: Arc<Server>,
    jobs: Arc<Jobs>,
    threads: Vec<JoinHandle<()>>,
}

impl ServerHandle {
    /// The page's address.
    pub fn url(&self) -> String {
        format!("http://{}/", self.addr)
    }

    /// Asks the server to stop (`reason` is what [`ServerHandle::wait`] returns).
    pub fn stop(&self, reason: &str) {
        stop(&self.stop, &self.reason, &self.server, &self.jobs, reason);
    }

    /// A flag that stops the server when set (for a Ctrl-C handler).
    pub fn stop_flag(&self) -> Arc<AtomicBool> {
        self.stop.clone()
    }

    /// Blocks until the server stops, joins its threads and returns why it
    /// stopped.
    pub fn wait(mut self) -> String {
        while !self.stop.load(Ordering::Relaxed) {
            std::thread::sleep(Duration::from_millis(100));
        }
        self.shutdown()
    }

    /// Stops the server, waits for its threads and returns why it stopped.
    pub fn shutdown(&mut self) -> String {
        self.stop("stopped");
        for t in self.threads.drain(..) {
            let _ = t.join();
        }
        self.reason
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .clone()
            .unwrap_or_else(|| "stopped".into())
    }
}

impl Drop for ServerHandle {
    fn drop(&mut self) {
        self.shutdown();
    }
}

fn stop(
    flag: &AtomicBool,
    reason: &Mutex<Option<String>>,
    server: &Server,
    jobs: &Jobs,
    why: &str,
) {
    let mut r = reason.lock().unwrap_or_else(|e| e.into_inner());
    if r.is_none() {
        *r = Some(why.to_string());
    }
    flag.store(true, Ordering::Relaxed);
    jobs.stop();
    server.unblock();
}

/// Starts serving `viewer`: request threads, the render worker and a
/// watcher that stops the server when the run directory disappears.
pub fn start(viewer: Arc<Viewer>, options: &ServerOptions) -> Result<ServerHandle, ViewerError> {
    let addr = format!("{}:{}", options.host, options.port);
    let server = Server::http(&addr).map_err(|e| ViewerError::Bind {
        addr: addr.clone(),
        reason: e.to_string(),
    })?;
    let bound = server
        .server_addr()
        .to_ip()
        .ok_or_else(|| ViewerError::Bind {
            addr: addr.clone(),
            reason: "not an IP address".into(),
        })?;
    let server = Arc::new(server);
    let stop_flag = Arc::new(AtomicBool::new(false));
    let reason = Arc::new(Mutex::new(None));
    let jobs = Arc::new(Jobs::default());
    let mut threads = Vec::new();
    for _ in 0..options.threads.max(1) {
        let (server, viewer, jobs, flag) = (
            server.clone(),
            viewer.clone(),
            jobs.clone(),
            stop_flag.clone(),
        );
        threads.push(std::thread::spawn(move || {
            while !flag.load(Ordering::Relaxed) {
                match server.recv_timeout(Duration::from_millis(200)) {
                    Ok(Some(request)) => answer(&viewer, &jobs, request),
                    Ok(None) => {}
                    Err(_) => std::thread::sleep(Duration::from_millis(50)),
                }
            }
        }));
    }
    {
        let (viewer, jobs) = (viewer.clone(), jobs.clone());
        threads.push(std::thread::spawn(move || jobs.work(&viewer)));
    }
    {
        let (server, jobs, flag, reason) = (
            server.clone(),
            jobs.clone(),
            stop_flag.clone(),
            reason.clone(),
        );
        let dir = viewer.data.run.dir.clone();
        threads.push(std::thread::spawn(move || {
            while !flag.load(Ordering::Relaxed) {
                if !dir.is_dir() {
                    let why = format!("the run directory {} is gone", dir.display());
                    stop(&flag, &reason, &server, &jobs, &why);
                    break;
                }
                std::thread::sleep(Duration::from_millis(250));
            }
            // A stop flag set from outside (Ctrl-C) still needs the
            // server unblocked and the worker stopped.
            stop(&flag, &reason, &server, &jobs, "stopped");
        }));
    }
    Ok(ServerHandle {
        addr: bound,
        stop: stop_flag,
        reason,
        server,
        jobs,
        threads,
    })
}

/// Reads the request's body (at most [`MAX_BODY`] bytes), answers it and
/// sends the reply; a client that went away is not an error of ours.
fn answer(viewer: &Viewer, jobs: &Jobs, mut request: tiny_http::Request) {
    let method = request.method().as_str().to_uppercase();
    let url = request.url().to_string();
    let reply = match read_body(&mut request) {
        Ok(body) => {
            // A panic in a handler (a defect) answers 500 instead of
            // leaving the client hanging.
            std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
                handle(viewer, jobs, &method, &url, &body)
            }))
            .unwrap_or_else(|_| {
                Reply::error(&ViewerError::Ops(field_ops::OpsError::Invalid(format!(
                    "{method} {url}: internal error"
                ))))
            })
        }
        Err(e) => Reply::error(&e),
    };
    // A known length (not chunks) lets the page show download progress and
    // keeps clients simple.
    let mut response = Response::from_data(reply.body)
        .with_chunked_threshold(usize::MAX)
        .with_status_code(reply.status)
        .with_header(header("Content-Type", reply.content_type))
        .with_header(header("Cache-Control", "no-store"));
    if let Some(name) = reply.filename {
        let value = format!("attachment; filename=\"{}\"", name.replace('"', "_"));
        response = response.with_header(header("Content-Disposition", &value));
    }
    let _ = request.respond(response);
}

fn read_body(request: &mut tiny_http::Request) -> Result<Vec<u8>, ViewerError> {
    if request.body_length().is_some_and(|n| n > MAX_BODY) {
        return Err(ViewerError::TooLarge { limit: MAX_BODY });
    }
    let mut body = Vec::new();
    request
        .as_reader()
        .take(MAX_BODY as u64 + 1)
        .read_to_end(&mut body)
        .map_err(|e| ViewerError::BadRequest(format!("request body: {e}")))?;
    if body.len() > MAX_BODY {
        return Err(ViewerError::TooLarge { limit: MAX_BODY });
    }
    Ok(body)
}

fn header(name: &str, value: &str) -> Header {
    Header::from_bytes(name.as_bytes(), value.as_bytes())
        .unwrap_or_else(|_| Header::from_bytes(&b"X-Invalid"[..], &b"1"[..]).expect("ascii header"))
}

/// What to print when the server starts: the page's address and, for a
/// server on another machine, the SSH tunnel that reaches it.
pub fn access_lines(addr: &SocketAddr) -> Vec<String> {
    let port = addr.port();
    let host = std::fs::read_to_string("/proc/sys/kernel/hostname")
        .map(|h| h.trim().to_string())
        .unwrap_or_else(|_| "this-machine".into());
    let user = std::env::var("USER").unwrap_or_else(|_| "you".into());
    let mut lines = vec![format!("viewer at http://{addr}/")];
    if addr.ip().is_unspecified() {
        lines.push(format!(
            "warning: listening on every network interface ({}): anyone who can reach this \
             machine can use the viewer; --host 127.0.0.1 keeps it local",
            addr.ip()
        ));
    }
    lines.push(format!(
        "from another machine: ssh -N -L {port}:127.0.0.1:{port} {user}@{host}   then open http://127.0.0.1:{port}/"
    ));
    lines.push("Ctrl-C stops the viewer".into());
    lines
}
