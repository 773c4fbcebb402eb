//! Storage servers on localhost for the tests of logs read by URL: an S3 endpoint (moto's
//! server, from the Python registry) and an HTTP server answering range requests.

use std::io::{BufRead, BufReader, Write};
use std::net::{TcpListener, TcpStream};
use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{Duration, Instant};

/// Set to `1` to skip the tests that need `moto_server` where it is not installed (locally
/// only: CI installs it, and there a missing server fails the tests).
pub const SKIP_S3: &str = "CALIB_SKIP_S3_TESTS";

/// A moto S3 server on a free port of 127.0.0.1, stopped when dropped.
pub struct Moto {
    child: Child,
    pub port: u16,
}

impl Drop for Moto {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// A free TCP port on 127.0.0.1.
fn free_port() -> u16 {
    TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

impl Moto {
    /// Starts `moto_server` (from `PATH`) and waits until it answers; `None` (the test then
    /// skips) only if it is missing and [`SKIP_S3`] is `1`.
    pub fn start() -> Option<Moto> {
        let port = free_port();
        let child = Command::new("moto_server")
            .args(["-H", "127.0.0.1", "-p", &port.to_string()])
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn();
        let child = match child {
            Ok(child) => child,
            Err(e) if std::env::var(SKIP_S3).as_deref() == Ok("1") => {
                eprintln!("skipped: moto_server cannot be started ({e}) and {SKIP_S3}=1");
                return None;
            }
            Err(e) => panic!(
                "moto_server cannot be started ({e}): install it (`pip install 'moto[server]'`, \
                 as .ci/run does) and put it on PATH, or set {SKIP_S3}=1 to skip these tests \
                 locally"
            ),
        };
        let moto = Moto { child, port };
        let start = Instant::now();
        while TcpStream::connect(("127.0.0.1", port)).is_err() {
            assert!(
                start.elapsed() < Duration::from_secs(60),
                "moto_server did not answer on port {port} within 60 s"
            );
            std::thread::sleep(Duration::from_millis(100));
        }
        Some(moto)
    }

    /// The endpoint's URL.
    pub fn endpoint(&self) -> String {
        format!("http://127.0.0.1:{}", self.port)
    }

    /// The environment that points the S3 client at this server, with credentials moto takes.
    pub fn env(&self) -> Vec<(&'static str, String)> {
        vec![
            ("AWS_ENDPOINT_URL", self.endpoint()),
            ("AWS_ALLOW_HTTP", "true".into()),
            ("AWS_ACCESS_KEY_ID", "testing".into()),
            ("AWS_SECRET_ACCESS_KEY", "testing".into()),
            ("AWS_REGION", "us-east-1".into()),
        ]
    }

    /// Creates the bucket `name`.
    pub fn bucket(&self, name: &str) {
        let status = request(self.port, "PUT", &format!("/{name}"), &[]);
        assert_eq!(status, 200, "creating bucket {name}");
    }

    /// Uploads `bytes` as `bucket/key`.
    pub fn put(&self, bucket: &str, key: &str, bytes: &[u8]) {
        let status = request(self.port, "PUT", &format!("/{bucket}/{key}"), bytes);
        assert_eq!(status, 200, "uploading {bucket}/{key}");
    }
}

/// One HTTP/1.1 request to 127.0.0.1:`port` without credentials (moto does not check them);
/// its status. Written by hand: bucket creation is no part of the `object_store` API, and two
/// requests do not justify an S3 client among the test dependencies.
fn request(port: u16, method: &str, path: &str, body: &[u8]) -> u16 {
    let mut stream = TcpStream::connect(("127.0.0.1", port)).unwrap();
    write!(
        stream,
        "{method} {path} HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nContent-Length: {}\r\n\
         Connection: close\r\n\r\n",
        body.len()
    )
    .unwrap();
    stream.write_all(body).unwrap();
    let mut status = String::new();
    BufReader::new(stream).read_line(&mut status).unwrap();
    status
        .split_whitespace()
        .nth(1)
        .and_then(|s| s.parse().ok())
        .unwrap_or_else(|| panic!("no HTTP status in {status:?}"))
}

/// An HTTP server on 127.0.0.1 serving the files of a folder, answering `HEAD` and `GET` with
/// a `Range: bytes=A-B` header (as object stores do; Python's `http.server` answers no ranges),
/// counting the body bytes it sends. It runs until the test process ends.
pub struct RangeServer {
    pub port: u16,
    pub sent: Arc<AtomicU64>,
}

impl RangeServer {
    pub fn start(root: PathBuf) -> RangeServer {
        let listener = TcpListener::bind("127.0.0.1:0").unwrap();
        let port = listener.local_addr().unwrap().port();
        let sent = Arc::new(AtomicU64::new(0));
        let counter = Arc::clone(&sent);
        std::thread::spawn(move || {
            for stream in listener.incoming().flatten() {
                let root = root.clone();
                let counter = Arc::clone(&counter);
                std::thread::spawn(move || serve(stream, &root, &counter));
            }
        });
        RangeServer { port, sent }
    }

    pub fn url(&self, name: &str) -> String {
        format!("http://127.0.0.1:{}/{name}", self.port)
    }

    pub fn sent(&self) -> u64 {
        self.sent.load(Ordering::Relaxed)
    }
}

/// Answers the requests of one connection (keep-alive) until the client closes it.
fn serve(stream: TcpStream, root: &std::path::Path, sent: &AtomicU64) {
    let mut reader = BufReader::new(stream.try_clone().unwrap());
    let mut out = stream;
    loop {
        let mut line = String::new();
        if reader.read_line(&mut line).unwrap_or(0) == 0 {
            return;
        }
        let mut parts = line.split_whitespace();
        let (method, path) = (parts.next().unwrap_or(""), parts.next().unwrap_or("/"));
        let mut range = None;
        loop {
            let mut header = String::new();
            if reader.read_line(&mut header).unwrap_or(0) == 0 {
                return;
            }
            let header = header.trim_end();
            if header.is_empty() {
                break;
            }
            if let Some((name, value)) = header.split_once(':')
                && name.eq_ignore_ascii_case("range")
            {
                let (a, b) = value
                    .trim()
                    .trim_start_matches("bytes=")
                    .split_once('-')
                    .unwrap();
                range = Some((a.parse::<u64>().unwrap(), b.parse::<u64>().ok()));
            }
        }
        let file = root.join(path.trim_start_matches('/'));
        let Ok(bytes) = std::fs::read(&file) else {
            let _ = write!(out, "HTTP/1.1 404 Not Found\r\nContent-Length: 0\r\n\r\n");
            continue;
        };
        let len = bytes.len() as u64;
        let head = method == "HEAD";
        let (status, body, extra) = match range {
            Some((a, b)) => {
                let b = b.unwrap_or(len - 1).min(len - 1);
                let body = &bytes[a as usize..=b as usize];
                (
                    "206 Partial Content",
                    body,
                    format!("Content-Range: bytes {a}-{b}/{len}\r\n"),
                )
            }
            None => ("200 OK", &bytes[..], String::new()),
        };
        let _ = write!(
            out,
            "HTTP/1.1 {status}\r\nContent-Length: {}\r\nAccept-Ranges: bytes\r\n{extra}\r\n",
            body.len()
        );
        if !head {
            let _ = out.write_all(body);
            sent.fetch_add(body.len() as u64, Ordering::Relaxed);
        }
        let _ = out.flush();
    }
}
