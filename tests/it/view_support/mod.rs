//! Driving `nephele view` from tests: the server as a child process (its URL read from its first
//! line), and headless Chromium (Debian's `chromium`) over the DevTools protocol on a pipe
//! (`--remote-debugging-pipe`: JSON messages ended by a NUL byte on the child's fds 3 and 4 —
//! no websocket client needed).

use std::fs::File;
use std::io::{BufRead, BufReader, Read, Write};
use std::os::fd::{FromRawFd, RawFd};
use std::os::unix::process::CommandExt;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use serde_json::{Value, json};

use crate::temp_support::{TempDir, temp_dir};

/// A running `nephele view`, stopped on drop.
pub struct View {
    child: Child,
    /// The page's URL (`http://127.0.0.1:PORT/`).
    pub url: String,
    /// Its port.
    pub port: u16,
}

impl View {
    /// `nephele view scene --cache cache`, run in `dir`; waits for its URL.
    pub fn start(dir: &Path, scene: &Path, cache: &Path) -> View {
        let mut child = crate::cli_support::nephele_in(dir)
            .arg("view")
            .arg(scene)
            .arg("--cache")
            .arg(cache)
            .stdout(Stdio::piped())
            .stderr(Stdio::inherit())
            .spawn()
            .expect("nephele view starts");
        let mut line = String::new();
        BufReader::new(child.stdout.take().unwrap())
            .read_line(&mut line)
            .unwrap();
        let url = line.trim().to_string();
        assert!(url.starts_with("http://127.0.0.1:"), "no URL: {line:?}");
        let port = url["http://127.0.0.1:".len()..]
            .trim_end_matches('/')
            .parse()
            .unwrap();
        View { child, url, port }
    }

    /// A raw HTTP/1.1 request to the server (`request` without the final blank line):
    /// the status code and the body.
    pub fn raw(&self, request: &str) -> (u16, String) {
        let mut s = std::net::TcpStream::connect(("127.0.0.1", self.port)).unwrap();
        s.set_read_timeout(Some(Duration::from_secs(60))).unwrap();
        write!(s, "{request}Connection: close\r\n\r\n").unwrap();
        let mut out = Vec::new();
        let _ = s.read_to_end(&mut out);
        let text = String::from_utf8_lossy(&out).into_owned();
        let status = text
            .split(' ')
            .nth(1)
            .and_then(|c| c.parse().ok())
            .unwrap_or(0);
        let body = text.split_once("\r\n\r\n").map_or("", |b| b.1).to_string();
        (status, body)
    }

    /// Wait (at most a minute) until the scene has loaded: its first generation exists.
    pub fn wait_loaded(&self) {
        let start = Instant::now();
        loop {
            let (_, state) = self.get("/state.json");
            let state: Value = serde_json::from_str(&state).unwrap_or(Value::Null);
            if state["current"].is_object() {
                return;
            }
            assert!(
                start.elapsed() < Duration::from_secs(60),
                "not loaded: {state}"
            );
            std::thread::sleep(Duration::from_millis(20));
        }
    }

    /// `GET path` with the right `Host`.
    pub fn get(&self, path: &str) -> (u16, String) {
        self.raw(&format!(
            "GET {path} HTTP/1.1\r\nHost: 127.0.0.1:{}\r\n",
            self.port
        ))
    }
}

impl Drop for View {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// Debian's Chromium, when installed.
pub fn chromium() -> Option<PathBuf> {
    ["/usr/bin/chromium", "/usr/bin/chromium-browser"]
        .into_iter()
        .map(PathBuf::from)
        .find(|p| p.exists())
}

/// A headless Chromium with one page attached, stopped on drop.
pub struct Browser {
    child: Child,
    to: File,
    from: BufReader<File>,
    next: u64,
    session: String,
    _profile: TempDir,
}

/// A pipe's two ends, close-on-exec, numbered 10 or above (so that the child's `dup2` onto 3
/// and 4 never meets one of them: `dup2(3, 3)` would keep close-on-exec).
fn pipe() -> (RawFd, RawFd) {
    let mut fds = [0; 2];
    // SAFETY: `fds` is two ints for pipe2 to fill; each end is moved above 9 and the low one
    // closed.
    unsafe {
        assert_eq!(libc::pipe2(fds.as_mut_ptr(), libc::O_CLOEXEC), 0);
        for fd in &mut fds {
            let high = libc::fcntl(*fd, libc::F_DUPFD_CLOEXEC, 10);
            assert!(high >= 10);
            libc::close(*fd);
            *fd = high;
        }
    }
    (fds[0], fds[1])
}

impl Browser {
    /// Start `chromium` headless and open `url` in a 1000×900 window.
    pub fn open(chromium: &Path, url: &str) -> Browser {
        // One profile a browser: tests run side by side in one process.
        static BROWSERS: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
        let n = BROWSERS.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        let profile = temp_dir(&format!("view-chromium-{n}"));
        let (to_read, to_write) = pipe();
        let (from_read, from_write) = pipe();
        let mut command = Command::new(chromium);
        command
            .args([
                "--headless=new",
                "--no-sandbox",
                "--remote-debugging-pipe",
                "--no-first-run",
                "--disable-gpu",
                "--force-color-profile=srgb",
                "--window-size=1000,900",
                "about:blank",
            ])
            .arg(format!("--user-data-dir={}", profile.display()))
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(Stdio::null());
        // SAFETY: only async-signal-safe dup2 calls between fork and exec.
        unsafe {
            command.pre_exec(move || {
                if libc::dup2(to_read, 3) < 0 || libc::dup2(from_write, 4) < 0 {
                    return Err(std::io::Error::last_os_error());
                }
                Ok(())
            });
        }
        let child = command.spawn().expect("chromium starts");
        // SAFETY: the parent's ends, owned from here on; the child's are closed in the parent.
        let (to, from) = unsafe {
            libc::close(to_read);
            libc::close(from_write);
            (File::from_raw_fd(to_write), File::from_raw_fd(from_read))
        };
        let mut b = Browser {
            child,
            to,
            from: BufReader::new(from),
            next: 0,
            session: String::new(),
            _profile: profile,
        };
        let target = b.send(None, "Target.createTarget", json!({"url": url}));
        let id = target["targetId"].as_str().unwrap().to_string();
        let attached = b.send(
            None,
            "Target.attachToTarget",
            json!({"targetId": id, "flatten": true}),
        );
        b.session = attached["sessionId"].as_str().unwrap().to_string();
        b
    }

    /// Send a DevTools command (to the page's session when `session`) and return its result.
    fn send(&mut self, session: Option<&str>, method: &str, params: Value) -> Value {
        self.next += 1;
        let id = self.next;
        let mut message = json!({"id": id, "method": method, "params": params});
        if let Some(s) = session {
            message["sessionId"] = json!(s);
        }
        let mut bytes = message.to_string().into_bytes();
        bytes.push(0);
        self.to.write_all(&bytes).unwrap();
        loop {
            let mut reply = Vec::new();
            let n = self.from.read_until(0, &mut reply).unwrap();
            assert!(n > 0, "chromium closed its DevTools pipe");
            reply.pop();
            let v: Value = serde_json::from_slice(&reply).unwrap();
            if v["id"] == json!(id) {
                assert!(v.get("error").is_none(), "{method}: {v}");
                return v["result"].clone();
            }
        }
    }

    /// Evaluate `js` in the page (a promise is awaited) and return its value.
    pub fn eval(&mut self, js: &str) -> Value {
        let session = self.session.clone();
        let r = self.send(
            Some(&session),
            "Runtime.evaluate",
            json!({"expression": js, "awaitPromise": true, "returnByValue": true}),
        );
        assert!(r.get("exceptionDetails").is_none(), "{js}: {r}");
        r["result"]["value"].clone()
    }

    /// Evaluate `js` every 10 ms until it gives something other than null/false, at most
    /// `timeout`; its value.
    #[track_caller]
    pub fn wait_for(&mut self, js: &str, timeout: Duration) -> Value {
        let start = Instant::now();
        // Not yet defined (the page still loading) counts as not yet.
        let guarded =
            format!("(() => {{ try {{ return {js}; }} catch (e) {{ return null; }} }})()");
        loop {
            let v = self.eval(&guarded);
            if !v.is_null() && v != json!(false) {
                return v;
            }
            assert!(start.elapsed() < timeout, "waited {timeout:?} for {js}");
            std::thread::sleep(Duration::from_millis(10));
        }
    }

    /// The RGB bytes of the page's picture (`#pic`) as displayed from its file: width, height,
    /// pixels.
    pub fn picture(&mut self) -> (u32, u32, Vec<u8>) {
        self.image("pic")
    }

    /// The RGB bytes of the page's image `#id` as loaded from its file: width, height, pixels.
    pub fn image(&mut self, id: &str) -> (u32, u32, Vec<u8>) {
        let v = self.eval(&format!(
            "(() => {{ const i = document.getElementById('{id}'); const c = \
             document.createElement('canvas'); c.width = i.naturalWidth; c.height = \
             i.naturalHeight; const x = c.getContext('2d'); x.drawImage(i, 0, 0); const d = \
             x.getImageData(0, 0, c.width, c.height).data; const rgb = []; for (let k = 0; k < \
             d.length; k += 4) rgb.push(d[k], d[k + 1], d[k + 2]); return [c.width, c.height, \
             rgb]; }})()",
        ));
        let rgb = v[2]
            .as_array()
            .unwrap()
            .iter()
            .map(|b| b.as_u64().unwrap() as u8)
            .collect();
        (
            v[0].as_u64().unwrap() as u32,
            v[1].as_u64().unwrap() as u32,
            rgb,
        )
    }
}

impl Browser {
    /// A PNG of the page as it is now (for looking at it).
    pub fn screenshot(&mut self) -> Vec<u8> {
        let session = self.session.clone();
        let r = self.send(
            Some(&session),
            "Page.captureScreenshot",
            json!({"format": "png"}),
        );
        base64(r["data"].as_str().unwrap())
    }
}

/// Standard base64 (the DevTools protocol's binary data) decoded.
fn base64(text: &str) -> Vec<u8> {
    let value = |c: u8| match c {
        b'A'..=b'Z' => c - b'A',
        b'a'..=b'z' => c - b'a' + 26,
        b'0'..=b'9' => c - b'0' + 52,
        b'+' => 62,
        _ => 63,
    };
    let digits: Vec<u8> = text.bytes().filter(|&c| c != b'=').map(value).collect();
    digits
        .chunks(4)
        .flat_map(|q| {
            let n = q
                .iter()
                .enumerate()
                .fold(0u32, |n, (i, &d)| n | (d as u32) << (18 - 6 * i));
            let bytes = [(n >> 16) as u8, (n >> 8) as u8, n as u8];
            bytes.into_iter().take(q.len().saturating_sub(1))
        })
        .collect()
}

impl Drop for Browser {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}
