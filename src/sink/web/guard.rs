//! What stands between the dashboard and the network (see [`super`]'s "Guarded"): the
//! token check, the request-size and method rules, the security headers, and a listener
//! that caps open connections and closes idle ones.

use std::future::Future;
use std::io;
use std::path::Path;
use std::pin::Pin;
use std::sync::Arc;
use std::task::{Context, Poll};

use axum::extract::{Request, State};
use axum::http::{header, HeaderValue, Method, StatusCode};
use axum::middleware::Next;
use axum::response::{IntoResponse, Response};
use sha2::{Digest, Sha256};
use tokio::io::{AsyncRead, AsyncWrite, ReadBuf};
use tokio::net::{TcpListener, TcpStream};
use tokio::sync::{OwnedSemaphorePermit, Semaphore};
use tokio::time::{Instant, Sleep};

use super::IDLE_TIMEOUT;

/// What every request is checked against, and the headers every response gets.
pub struct Rules {
    token: Option<String>,
    max_request_bytes: usize,
    csp: HeaderValue,
}

impl Rules {
    /// Rules for this token and size limit; the CSP allows exactly the inline `<script>` and
    /// `<style>` of `page` (by hash), so nothing injected could run.
    pub fn new(token: Option<String>, max_request_bytes: usize, page: &str) -> Self {
        let hash = |open: &str, close: &str| {
            let body = page
                .split_once(open)
                .and_then(|(_, rest)| rest.split_once(close))
                .map_or("", |(b, _)| b);
            format!("'sha256-{}'", base64(&Sha256::digest(body.as_bytes())))
        };
        let csp = format!(
            "default-src 'none'; script-src {}; style-src {}; connect-src 'self'; img-src 'self' data:; \
             base-uri 'none'; form-action 'none'; frame-ancestors 'none'",
            hash("<script>", "</script>"),
            hash("<style>", "</style>")
        );
        // A hash and fixed words: always a valid header value.
        let csp = HeaderValue::from_str(&csp)
            .unwrap_or_else(|_| HeaderValue::from_static("default-src 'none'"));
        Self {
            token,
            max_request_bytes,
            csp,
        }
    }
}

/// The middleware: size and method rules, the token for `/api/*`, then the headers.
pub async fn check(State(rules): State<Arc<Rules>>, req: Request, next: Next) -> Response {
    let mut resp = match admit(&rules, &req) {
        Some(refusal) => refusal,
        None => next.run(req).await,
    };
    let h = resp.headers_mut();
    h.insert(header::CONTENT_SECURITY_POLICY, rules.csp.clone());
    h.insert(
        header::X_CONTENT_TYPE_OPTIONS,
        HeaderValue::from_static("nosniff"),
    );
    h.insert(
        header::REFERRER_POLICY,
        HeaderValue::from_static("no-referrer"),
    );
    h.insert(header::X_FRAME_OPTIONS, HeaderValue::from_static("DENY"));
    h.insert(header::CACHE_CONTROL, HeaderValue::from_static("no-store"));
    h.insert(
        "cross-origin-resource-policy",
        HeaderValue::from_static("same-origin"),
    );
    resp
}

/// `Some(refusal)` when the request breaks a rule.
fn admit(rules: &Rules, req: &Request) -> Option<Response> {
    let head_bytes = req.uri().to_string().len()
        + req
            .headers()
            .iter()
            .map(|(k, v)| k.as_str().len() + v.as_bytes().len() + 4)
            .sum::<usize>();
    if head_bytes > rules.max_request_bytes {
        return Some(
            (
                StatusCode::REQUEST_HEADER_FIELDS_TOO_LARGE,
                "request too large\n",
            )
                .into_response(),
        );
    }
    let has_body = req.headers().contains_key(header::TRANSFER_ENCODING)
        || req
            .headers()
            .get(header::CONTENT_LENGTH)
            .is_some_and(|v| v.as_bytes() != b"0");
    if has_body {
        return Some(
            (
                StatusCode::PAYLOAD_TOO_LARGE,
                "this dashboard takes no request bodies\n",
            )
                .into_response(),
        );
    }
    if req.method() != Method::GET && req.method() != Method::HEAD {
        let mut r = (StatusCode::METHOD_NOT_ALLOWED, "read only\n").into_response();
        r.headers_mut()
            .insert(header::ALLOW, HeaderValue::from_static("GET, HEAD"));
        return Some(r);
    }
    let token = rules.token.as_deref()?;
    if !req.uri().path().starts_with("/api/") {
        return None; // the page itself holds no data
    }
    let presented = req
        .headers()
        .get(header::AUTHORIZATION)
        .and_then(|v| v.as_bytes().strip_prefix(b"Bearer "));
    if presented.is_some_and(|p| same(p, token.as_bytes())) {
        return None;
    }
    let mut r = (
        StatusCode::UNAUTHORIZED,
        "a token is needed: Authorization: Bearer TOKEN\n",
    )
        .into_response();
    r.headers_mut().insert(
        header::WWW_AUTHENTICATE,
        HeaderValue::from_static("Bearer realm=\"dronewatt\""),
    );
    Some(r)
}

/// Equal, in time that depends on the lengths only.
fn same(a: &[u8], b: &[u8]) -> bool {
    subtle::ConstantTimeEq::ct_eq(a, b).into()
}

/// Standard base64 with padding (for the CSP hashes).
fn base64(bytes: &[u8]) -> String {
    use base64::Engine;
    base64::engine::general_purpose::STANDARD.encode(bytes)
}

/// A secret from a file private to its owner (Unix: no group or other access), trimmed.
pub fn read_private(path: &Path) -> Result<String, String> {
    Ok(crate::files::read_private_text(path)?.trim().to_string())
}

/// A listener that holds at most `max` connections open: the next accept waits for a
/// permit, so extra clients wait in the kernel's backlog instead of costing memory.
pub struct Limited {
    inner: TcpListener,
    permits: Arc<Semaphore>,
}

impl Limited {
    /// Wrap `inner`, allowing `max` connections at once.
    pub fn new(inner: TcpListener, max: usize) -> Self {
        Self {
            inner,
            permits: Arc::new(Semaphore::new(max)),
        }
    }
}

impl axum::serve::Listener for Limited {
    type Io = Guarded;
    type Addr = std::net::SocketAddr;

    async fn accept(&mut self) -> (Guarded, std::net::SocketAddr) {
        loop {
            // The semaphore is never closed, so this only waits.
            let Ok(permit) = self.permits.clone().acquire_owned().await else {
                continue;
            };
            match self.inner.accept().await {
                Ok((io, addr)) => {
                    let _ = io.set_nodelay(true);
                    let idle = Box::pin(tokio::time::sleep(IDLE_TIMEOUT));
                    return (
                        Guarded {
                            io,
                            idle,
                            _permit: permit,
                        },
                        addr,
                    );
                }
                Err(e) => {
                    // Out of file descriptors and the like: wait a little, as axum does.
                    tracing::debug!("web dashboard: accept: {e}");
                    tokio::time::sleep(std::time::Duration::from_millis(50)).await;
                }
            }
        }
    }

    fn local_addr(&self) -> io::Result<std::net::SocketAddr> {
        self.inner.local_addr()
    }
}

/// One accepted connection: its permit goes back when it is dropped, and it fails with
/// `TimedOut` once nothing was read or written for [`IDLE_TIMEOUT`].
pub struct Guarded {
    io: TcpStream,
    idle: Pin<Box<Sleep>>,
    _permit: OwnedSemaphorePermit,
}

impl Guarded {
    /// After an I/O step: progress resets the idle clock; no progress past it is an error.
    fn watch<T>(&mut self, cx: &mut Context<'_>, r: Poll<io::Result<T>>) -> Poll<io::Result<T>> {
        match r {
            Poll::Ready(r) => {
                self.idle.as_mut().reset(Instant::now() + IDLE_TIMEOUT);
                Poll::Ready(r)
            }
            Poll::Pending => match self.idle.as_mut().poll(cx) {
                Poll::Ready(()) => Poll::Ready(Err(io::ErrorKind::TimedOut.into())),
                Poll::Pending => Poll::Pending,
            },
        }
    }
}

impl AsyncRead for Guarded {
    fn poll_read(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        buf: &mut ReadBuf<'_>,
    ) -> Poll<io::Result<()>> {
        let r = Pin::new(&mut self.io).poll_read(cx, buf);
        self.watch(cx, r)
    }
}

impl AsyncWrite for Guarded {
    fn poll_write(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        buf: &[u8],
    ) -> Poll<io::Result<usize>> {
        let r = Pin::new(&mut self.io).poll_write(cx, buf);
        self.watch(cx, r)
    }
    fn poll_flush(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        Pin::new(&mut self.io).poll_flush(cx)
    }
    fn poll_shutdown(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        Pin::new(&mut self.io).poll_shutdown(cx)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn base64_matches_rfc4648_vectors() {
        for (raw, enc) in [
            ("", ""),
            ("f", "Zg=="),
            ("fo", "Zm8="),
            ("foo", "Zm9v"),
            ("foobar", "Zm9vYmFy"),
        ] {
            assert_eq!(base64(raw.as_bytes()), enc);
        }
    }

    #[test]
    fn the_csp_pins_the_pages_own_script() {
        let page = "<style>b{}</style><script>go()</script>";
        let rules = Rules::new(None, 8192, page);
        let csp = rules.csp.to_str().unwrap();
        let script = format!("script-src 'sha256-{}'", base64(&Sha256::digest(b"go()")));
        assert!(csp.contains(&script) && !csp.contains("unsafe"), "{csp}");
        assert!(
            !same(b"secret-token-0001", b"secret-token-0002")
                && same(b"abc", b"abc")
                && !same(b"ab", b"abc")
        );
    }
}
