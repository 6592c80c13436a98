//! The preview's HTTP/1.1 connection layer: a fixed pool of request threads, a cap on open
//! connections, and timeouts for reading a request, for idling between requests and for writing
//! a reply.
//!
//! Why not tiny_http: it reads every connection on a thread of its own and grows that pool
//! without bound (500 idle connections made 504 threads), and it has no read or idle timeouts to
//! set. So the preview serves itself, with std and `poll(2)`:
//!
//! - One poller thread owns the listening socket and every connection that is not being
//!   answered. It reads them without blocking and hands a connection to the pool only once a
//!   whole request head has arrived, so an idle or slow client never holds a request thread.
//! - [`Limits::workers`] request threads answer requests (they may wait for a frame), and give a
//!   kept-alive connection back to the poller.
//! - At [`Limits::max_connections`] open connections a new one closes the one idle longest
//!   (idle connections cost the server nothing to drop; a browser reconnects); when every
//!   connection is being answered the new one gets 503.
//! - A request head must arrive within [`Limits::header_timeout`] of its first byte (else 408)
//!   and within [`Limits::max_header_bytes`] (else 431); a connection idle for
//!   [`Limits::idle_timeout`] is closed; a reply not taken within [`Limits::write_timeout`] is
//!   dropped.
//!
//! Requests with a body are answered and their connection closed (the preview only serves GET).

use std::io::{self, Read, Write};
use std::net::{TcpListener, TcpStream};
use std::os::fd::AsRawFd;
use std::os::unix::net::UnixStream;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::mpsc;
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// The server's bounds.
#[derive(Clone, Copy, Debug)]
pub(super) struct Limits {
    /// Request threads (each answers one request at a time).
    pub workers: usize,
    /// Open connections at most, idle ones and those being answered together.
    pub max_connections: usize,
    pub header_timeout: Duration,
    pub idle_timeout: Duration,
    pub write_timeout: Duration,
    pub max_header_bytes: usize,
}

impl Default for Limits {
    fn default() -> Self {
        Limits {
            workers: 8,
            max_connections: 128,
            header_timeout: Duration::from_secs(10),
            idle_timeout: Duration::from_secs(30),
            write_timeout: Duration::from_secs(10),
            max_header_bytes: 16 * 1024,
        }
    }
}

/// A request head.
#[derive(Clone, Debug)]
pub(super) struct Request {
    pub method: String,
    /// The request target as sent (`/api/frame/3.png?exposure=1`).
    pub target: String,
    /// The `Host` header, if there was exactly one.
    pub host: Option<String>,
    keep_alive: bool,
}

/// A reply: status, extra headers (Content-Length and Connection are added) and body.
pub(super) struct Response {
    pub status: u16,
    pub headers: Vec<(&'static str, String)>,
    pub body: Vec<u8>,
}

type Handler = dyn Fn(&Request) -> Response + Send + Sync;

/// One client connection and what it has sent that is not answered yet.
struct Conn {
    stream: TcpStream,
    buffer: Vec<u8>,
    /// When the connection went idle, or when the first byte of the pending request came.
    since: Instant,
}

/// A connection with a request to answer (or a request that cannot be read: status, message).
struct Job {
    conn: Conn,
    request: Result<Request, (u16, &'static str)>,
}

/// The running server; [`HttpServer::stop`] ends its threads.
pub(super) struct HttpServer {
    stop: Arc<AtomicBool>,
    wake: Arc<UnixStream>,
    threads: Vec<JoinHandle<()>>,
}

impl HttpServer {
    /// Serves `listener` with `handler` on `limits.workers` request threads and one poller.
    pub fn start(
        listener: TcpListener,
        limits: Limits,
        handler: Arc<Handler>,
    ) -> io::Result<HttpServer> {
        listener.set_nonblocking(true)?;
        let (wake_reader, wake_writer) = UnixStream::pair()?;
        wake_reader.set_nonblocking(true)?;
        wake_writer.set_nonblocking(true)?;
        let wake = Arc::new(wake_writer);
        let stop = Arc::new(AtomicBool::new(false));
        let (job_sender, job_receiver) = mpsc::channel::<Job>();
        let (return_sender, return_receiver) = mpsc::channel::<Conn>();
        let job_receiver = Arc::new(Mutex::new(job_receiver));
        let answering = Arc::new(AtomicUsize::new(0));
        let mut threads = Vec::new();
        for index in 0..limits.workers.max(1) {
            let context = WorkerContext {
                jobs: Arc::clone(&job_receiver),
                returns: return_sender.clone(),
                wake: Arc::clone(&wake),
                stop: Arc::clone(&stop),
                answering: Arc::clone(&answering),
                handler: Arc::clone(&handler),
                limits,
            };
            threads.push(
                std::thread::Builder::new()
                    .name(format!("preview-http-{index}"))
                    .spawn(move || context.run())?,
            );
        }
        drop(return_sender);
        let poller = Poller {
            listener,
            wake: wake_reader,
            returns: return_receiver,
            jobs: job_sender,
            stop: Arc::clone(&stop),
            answering,
            limits,
            conns: Vec::new(),
        };
        threads.push(
            std::thread::Builder::new()
                .name("preview-poll".into())
                .spawn(move || poller.run())?,
        );
        Ok(HttpServer {
            stop,
            wake,
            threads,
        })
    }

    /// Threads the server runs (request threads and the poller).
    pub fn thread_count(&self) -> usize {
        self.threads.len()
    }

    /// Closes the socket and every connection; returns once the request threads have finished
    /// the requests they were answering.
    pub fn stop(self) {
        self.stop.store(true, Ordering::SeqCst);
        let _ = (&*self.wake).write(&[1]);
        for thread in self.threads {
            let _ = thread.join();
        }
    }
}

struct Poller {
    listener: TcpListener,
    wake: UnixStream,
    returns: mpsc::Receiver<Conn>,
    jobs: mpsc::Sender<Job>,
    stop: Arc<AtomicBool>,
    /// Connections the request threads hold.
    answering: Arc<AtomicUsize>,
    limits: Limits,
    /// Connections waiting for (the rest of) a request.
    conns: Vec<Conn>,
}

impl Poller {
    fn run(mut self) {
        let mut fds: Vec<libc::pollfd> = Vec::new();
        loop {
            fds.clear();
            let entry = |fd: i32| libc::pollfd {
                fd,
                events: libc::POLLIN,
                revents: 0,
            };
            fds.push(entry(self.wake.as_raw_fd()));
            fds.push(entry(self.listener.as_raw_fd()));
            fds.extend(self.conns.iter().map(|c| entry(c.stream.as_raw_fd())));
            // A short timeout: timeouts are checked at least this often.
            // SAFETY: `fds` is a valid array of `fds.len()` pollfd structures.
            let ready = unsafe { libc::poll(fds.as_mut_ptr(), fds.len() as libc::nfds_t, 250) };
            if ready < 0 && io::Error::last_os_error().kind() != io::ErrorKind::Interrupted {
                // Nothing sensible is left to do with a failing poll but to wait and retry.
                std::thread::sleep(Duration::from_millis(50));
            }
            if self.stop.load(Ordering::SeqCst) {
                return; // drops the listener, every idle connection and the job queue
            }
            if fds[0].revents != 0 {
                let mut sink = [0u8; 64];
                while matches!((&self.wake).read(&mut sink), Ok(n) if n > 0) {}
            }
            // Read what the polled connections sent (connections returned below were not
            // polled: their `revents` are not in `fds`).
            let polled = self.conns.len();
            let mut closed = vec![false; polled];
            for (index, conn) in self.conns.iter_mut().enumerate() {
                if fds[index + 2].revents != 0 {
                    closed[index] = !read_available(conn, self.limits.max_header_bytes);
                }
            }
            let mut index = polled;
            while index > 0 {
                index -= 1;
                if closed[index] {
                    self.conns.swap_remove(index);
                }
            }
            while let Ok(mut conn) = self.returns.try_recv() {
                if conn.stream.set_nonblocking(true).is_ok() {
                    conn.since = Instant::now();
                    self.conns.push(conn);
                }
            }
            self.dispatch_or_expire();
            if fds[1].revents != 0 {
                self.accept();
            }
        }
    }

    /// Hands complete requests to the pool; answers over-long and over-slow ones; closes
    /// connections idle too long.
    fn dispatch_or_expire(&mut self) {
        let now = Instant::now();
        let mut index = 0;
        while index < self.conns.len() {
            let conn = &self.conns[index];
            let waited = now.saturating_duration_since(conn.since);
            let request = if let Some(request) = take_request(&conn.buffer) {
                Some(request)
            } else if conn.buffer.len() > self.limits.max_header_bytes {
                Some(Err((431, "the request head is too large")))
            } else if !conn.buffer.is_empty() && waited > self.limits.header_timeout {
                Some(Err((408, "the request head did not arrive in time")))
            } else if conn.buffer.is_empty() && waited > self.limits.idle_timeout {
                self.conns.swap_remove(index);
                continue;
            } else {
                None
            };
            match request {
                Some(request) => {
                    let conn = self.conns.swap_remove(index);
                    self.answering.fetch_add(1, Ordering::SeqCst);
                    if self.jobs.send(Job { conn, request }).is_err() {
                        self.answering.fetch_sub(1, Ordering::SeqCst);
                    }
                }
                None => index += 1,
            }
        }
    }

    fn accept(&mut self) {
        loop {
            let stream = match self.listener.accept() {
                Ok((stream, _)) => stream,
                Err(error) if error.kind() == io::ErrorKind::WouldBlock => return,
                Err(error) if error.kind() == io::ErrorKind::Interrupted => continue,
                // Out of descriptors, a connection reset before accept: try again at the next poll.
                Err(_) => return,
            };
            if stream.set_nonblocking(true).is_err() {
                continue;
            }
            let _ = stream.set_nodelay(true);
            let open = self.conns.len() + self.answering.load(Ordering::SeqCst);
            if open >= self.limits.max_connections {
                // Drop the connection idle longest; when all are being answered, refuse.
                let oldest = (0..self.conns.len()).min_by_key(|&i| self.conns[i].since);
                match oldest {
                    Some(index) => {
                        self.conns.swap_remove(index);
                    }
                    None => {
                        let reply = format_head(
                            503,
                            &[("Content-Type", "text/plain".to_string())],
                            0,
                            false,
                        );
                        let _ = (&stream).write(reply.as_bytes());
                        continue;
                    }
                }
            }
            self.conns.push(Conn {
                stream,
                buffer: Vec::new(),
                since: Instant::now(),
            });
        }
    }
}

/// Reads what `conn` has sent without blocking; false when the client closed it or it failed.
fn read_available(conn: &mut Conn, max_header_bytes: usize) -> bool {
    let mut chunk = [0u8; 4096];
    loop {
        match conn.stream.read(&mut chunk) {
            Ok(0) => return false,
            Ok(n) => {
                if conn.buffer.is_empty() {
                    conn.since = Instant::now();
                }
                conn.buffer.extend_from_slice(&chunk[..n]);
                if conn.buffer.len() > max_header_bytes {
                    return true; // answered with 431; the rest is not read
                }
            }
            Err(error) if error.kind() == io::ErrorKind::WouldBlock => return true,
            Err(error) if error.kind() == io::ErrorKind::Interrupted => continue,
            Err(_) => return false,
        }
    }
}

/// The request at the start of `buffer` once its head is complete.
fn take_request(buffer: &[u8]) -> Option<Result<Request, (u16, &'static str)>> {
    let end = buffer.windows(4).position(|w| w == b"\r\n\r\n")?;
    Some(parse_head(&buffer[..end]))
}

/// Bytes of the request head at the start of `buffer`, its blank line included.
fn head_length(buffer: &[u8]) -> Option<usize> {
    buffer
        .windows(4)
        .position(|w| w == b"\r\n\r\n")
        .map(|end| end + 4)
}

fn parse_head(head: &[u8]) -> Result<Request, (u16, &'static str)> {
    const BAD: (u16, &str) = (400, "the request head is not HTTP/1.x");
    let head = std::str::from_utf8(head).map_err(|_| BAD)?;
    let mut lines = head.split("\r\n");
    let mut words = lines.next().unwrap_or("").split(' ');
    let (Some(method), Some(target), Some(version), None) =
        (words.next(), words.next(), words.next(), words.next())
    else {
        return Err(BAD);
    };
    let http_11 = match version {
        "HTTP/1.1" => true,
        "HTTP/1.0" => false,
        _ => return Err((505, "only HTTP/1.0 and HTTP/1.1 are served")),
    };
    if method.is_empty() || !target.starts_with('/') {
        return Err(BAD);
    }
    let mut hosts = Vec::new();
    let mut connection = String::new();
    let mut has_body = false;
    for line in lines {
        let (name, value) = line.split_once(':').ok_or(BAD)?;
        let value = value.trim();
        if name.eq_ignore_ascii_case("host") {
            hosts.push(value.to_string());
        } else if name.eq_ignore_ascii_case("connection") {
            connection = value.to_ascii_lowercase();
        } else if name.eq_ignore_ascii_case("transfer-encoding")
            || (name.eq_ignore_ascii_case("content-length") && value != "0")
        {
            has_body = true;
        }
    }
    if hosts.len() > 1 {
        return Err((400, "more than one Host header"));
    }
    let keep_alive = !has_body
        && if http_11 {
            !connection.contains("close")
        } else {
            connection.contains("keep-alive")
        };
    Ok(Request {
        method: method.to_string(),
        target: target.to_string(),
        host: hosts.pop(),
        keep_alive,
    })
}

fn reason(status: u16) -> &'static str {
    match status {
        200 => "OK",
        400 => "Bad Request",
        403 => "Forbidden",
        404 => "Not Found",
        405 => "Method Not Allowed",
        408 => "Request Timeout",
        409 => "Conflict",
        421 => "Misdirected Request",
        422 => "Unprocessable Content",
        431 => "Request Header Fields Too Large",
        500 => "Internal Server Error",
        503 => "Service Unavailable",
        505 => "HTTP Version Not Supported",
        _ => "Status",
    }
}

fn format_head(
    status: u16,
    headers: &[(&str, String)],
    content_length: usize,
    keep_alive: bool,
) -> String {
    let mut head = format!("HTTP/1.1 {status} {}\r\n", reason(status));
    for (name, value) in headers {
        head.push_str(&format!("{name}: {value}\r\n"));
    }
    head.push_str(&format!(
        "Content-Length: {content_length}\r\nConnection: {}\r\n\r\n",
        if keep_alive { "keep-alive" } else { "close" }
    ));
    head
}

struct WorkerContext {
    jobs: Arc<Mutex<mpsc::Receiver<Job>>>,
    returns: mpsc::Sender<Conn>,
    wake: Arc<UnixStream>,
    stop: Arc<AtomicBool>,
    answering: Arc<AtomicUsize>,
    handler: Arc<Handler>,
    limits: Limits,
}

impl WorkerContext {
    fn run(self) {
        loop {
            let job = {
                let jobs = self.jobs.lock().unwrap_or_else(|p| p.into_inner());
                jobs.recv()
            };
            let Ok(job) = job else { return };
            if let Some(conn) = self.answer(job) {
                if self.returns.send(conn).is_ok() {
                    let _ = (&*self.wake).write(&[1]);
                }
            }
            self.answering.fetch_sub(1, Ordering::SeqCst);
        }
    }

    /// Answers the job's request and any complete ones after it; returns a connection to keep.
    fn answer(&self, job: Job) -> Option<Conn> {
        let Job { mut conn, request } = job;
        conn.stream.set_nonblocking(false).ok()?;
        conn.stream
            .set_write_timeout(Some(self.limits.write_timeout))
            .ok()?;
        let mut request = request;
        loop {
            let consumed = head_length(&conn.buffer).unwrap_or(conn.buffer.len());
            conn.buffer.drain(..consumed);
            let (response, keep_alive) = match &request {
                Ok(request) => {
                    let response = crate::panics::catch(|| (self.handler)(request)).unwrap_or_else(
                        |message| Response {
                            status: 500,
                            headers: vec![("Content-Type", "application/json".to_string())],
                            body: serde_json::to_vec(&serde_json::json!({
                                "error": format!("the preview failed on this request: {message}")
                            }))
                            .expect("JSON values serialise"),
                        },
                    );
                    (response, request.keep_alive)
                }
                Err((status, message)) => (
                    Response {
                        status: *status,
                        headers: vec![("Content-Type", "application/json".to_string())],
                        body: serde_json::to_vec(&serde_json::json!({ "error": message }))
                            .expect("JSON values serialise"),
                    },
                    false,
                ),
            };
            let keep_alive = keep_alive && !self.stop.load(Ordering::SeqCst);
            let head = format_head(
                response.status,
                &response.headers,
                response.body.len(),
                keep_alive,
            );
            let written = conn
                .stream
                .write_all(head.as_bytes())
                .and_then(|()| conn.stream.write_all(&response.body))
                .and_then(|()| conn.stream.flush());
            // The client may have gone (a scrubbing page drops requests it no longer needs).
            if written.is_err() || !keep_alive {
                return None;
            }
            match take_request(&conn.buffer) {
                Some(next) => request = next,
                None => return Some(conn),
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn request_heads_are_parsed_and_bad_ones_refused() {
        let request = parse_head(b"GET /api/scene?x=1 HTTP/1.1\r\nHost: 127.0.0.1:80").unwrap();
        assert_eq!(request.method, "GET");
        assert_eq!(request.target, "/api/scene?x=1");
        assert_eq!(request.host.as_deref(), Some("127.0.0.1:80"));
        assert!(request.keep_alive);
        let request = parse_head(b"GET / HTTP/1.1\r\nHost: a\r\nConnection: close").unwrap();
        assert!(!request.keep_alive);
        let request = parse_head(b"GET / HTTP/1.0\r\nHost: a").unwrap();
        assert!(!request.keep_alive);
        let request = parse_head(b"GET / HTTP/1.0\r\nConnection: Keep-Alive").unwrap();
        assert!(request.keep_alive && request.host.is_none());
        let request = parse_head(b"POST / HTTP/1.1\r\nHost: a\r\nContent-Length: 5").unwrap();
        assert!(
            !request.keep_alive,
            "a body is not read: the connection closes"
        );
        assert_eq!(parse_head(b"GET / HTTP/2.0").unwrap_err().0, 505);
        for bad in [
            &b"GET /"[..],
            b"GET  / HTTP/1.1",
            b"GET http://x/ HTTP/1.1",
            b"GET / HTTP/1.1\r\nno colon",
            b"GET / HTTP/1.1\r\nHost: a\r\nHost: b",
            b"\xff / HTTP/1.1",
        ] {
            assert_eq!(
                parse_head(bad).unwrap_err().0,
                400,
                "{}",
                String::from_utf8_lossy(bad)
            );
        }
        assert!(take_request(b"GET / HTTP/1.1\r\nHost: a\r\n").is_none());
        assert_eq!(head_length(b"GET / HTTP/1.1\r\n\r\nGET"), Some(18));
    }
}
