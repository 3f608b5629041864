//! A UDP link's socket sized for a fleet: the receive buffer asked of the kernel, and how
//! many datagrams one wake-up of the link reads before it hands their messages on.

/// The UDP receive buffer asked for: a fleet of thousands of vehicles sends tens of
/// thousands of datagrams a second, and the kernel drops what arrives while the buffer is
/// full (Linux's default, ~208 KiB, holds a few hundred). The kernel caps it at
/// `net.core.rmem_max`; the size it grants is logged.
pub const UDP_RCVBUF: usize = 16 << 20;
/// Most datagrams read per wake-up of a UDP link before what they hold is handed on.
pub(super) const RECV_BURST: usize = 256;

/// Ask for [`UDP_RCVBUF`] on `sock`; the size the kernel granted (0: not known).
pub(super) fn grow_receive_buffer(sock: &tokio::net::UdpSocket) -> usize {
    use std::os::fd::AsRawFd;
    let fd = sock.as_raw_fd();
    let want = libc::c_int::try_from(UDP_RCVBUF).unwrap_or(libc::c_int::MAX);
    let size = std::mem::size_of::<libc::c_int>() as libc::socklen_t;
    // SAFETY: fd is an open socket owned by `sock`; the option values are c_ints of the
    // size passed.
    unsafe {
        libc::setsockopt(
            fd,
            libc::SOL_SOCKET,
            libc::SO_RCVBUF,
            (&want as *const libc::c_int).cast(),
            size,
        );
        let mut got: libc::c_int = 0;
        let mut len = size;
        if libc::getsockopt(
            fd,
            libc::SOL_SOCKET,
            libc::SO_RCVBUF,
            (&mut got as *mut libc::c_int).cast(),
            &mut len,
        ) != 0
        {
            return 0;
        }
        usize::try_from(got).unwrap_or(0)
    }
}

/// Read what else `sock` holds now (at most [`RECV_BURST`] − 1 datagrams, never waiting)
/// into `reader`; the newest sender, if any was read.
pub(super) fn drain(
    sock: &tokio::net::UdpSocket,
    buf: &mut [u8],
    reader: &mut crate::source::frame::timed::TimedReader,
    label: &str,
) -> Option<std::net::SocketAddr> {
    let mut newest = None;
    for _ in 1..RECV_BURST {
        match sock.try_recv_from(buf) {
            Ok((n, from)) => {
                newest = Some(from);
                reader.push(&buf[..n]);
            }
            Err(e) => {
                if e.kind() != std::io::ErrorKind::WouldBlock {
                    tracing::debug!("{label}: receive: {e}");
                }
                break;
            }
        }
    }
    newest
}
