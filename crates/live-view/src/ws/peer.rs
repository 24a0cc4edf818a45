//! Who is on the other end of a loopback TCP connection: the Unix user owning the client's
//! socket. `SO_PEERCRED` answers only for Unix sockets; for TCP the kernel lists every socket
//! of this network namespace with its owner in `/proc/net/tcp` and `/proc/net/tcp6`, and the
//! client's socket is the one whose local address is our peer and whose remote address is us.

use std::net::{IpAddr, Ipv6Addr, SocketAddr};

/// The uid owning the client socket of the connection from `peer` to `local` (both as this
/// side sees them), if the kernel lists it.
pub fn uid_of(local: SocketAddr, peer: SocketAddr) -> Option<u32> {
    ["/proc/net/tcp", "/proc/net/tcp6"]
        .iter()
        .find_map(|table| {
            let text = read_bounded(table)?;
            text.lines()
                .skip(1)
                .find_map(|line| owner(line, (peer, local)))
        })
}

/// The table's text (bounded: a host with a million sockets is not read whole).
fn read_bounded(path: &str) -> Option<String> {
    use std::io::Read;
    let mut text = String::new();
    std::fs::File::open(path)
        .ok()?
        .take(64 << 20)
        .read_to_string(&mut text)
        .ok()?;
    Some(text)
}

/// The uid of a table line whose (local, remote) addresses are `want`.
fn owner(line: &str, want: (SocketAddr, SocketAddr)) -> Option<u32> {
    let fields: Vec<&str> = line.split_whitespace().collect();
    let (local, remote) = (address(fields.get(1)?)?, address(fields.get(2)?)?);
    (same(local, want.0) && same(remote, want.1)).then(|| fields.get(7)?.parse().ok())?
}

/// `"0100007F:1F90"` (IPv4) or 32 hex digits and a port (IPv6): each 32-bit word of the
/// address is printed as the kernel holds it (host order), the port in plain hex.
fn address(field: &str) -> Option<SocketAddr> {
    let (ip, port) = field.split_once(':')?;
    let port = u16::from_str_radix(port, 16).ok()?;
    let words: Option<Vec<[u8; 4]>> = (0..ip.len() / 8)
        .map(|i| {
            let w = u32::from_str_radix(ip.get(8 * i..8 * i + 8)?, 16).ok()?;
            Some(w.to_ne_bytes())
        })
        .collect();
    let bytes: Vec<u8> = words?.concat();
    let ip = match bytes.len() {
        4 => IpAddr::from(<[u8; 4]>::try_from(bytes).ok()?),
        16 => IpAddr::from(<[u8; 16]>::try_from(bytes).ok()?),
        _ => return None,
    };
    Some(SocketAddr::new(ip, port))
}

/// Equal addresses, an IPv4 address equal to its IPv4-mapped IPv6 form.
fn same(a: SocketAddr, b: SocketAddr) -> bool {
    let canonical = |ip: IpAddr| match ip {
        IpAddr::V6(v6) => v6.to_ipv4_mapped().map_or(IpAddr::V6(v6), IpAddr::V4),
        v4 => v4,
    };
    a.port() == b.port() && canonical(a.ip()) == canonical(b.ip())
}

/// Whether `ip` is a loopback address (IPv4-mapped included).
pub fn is_loopback(ip: IpAddr) -> bool {
    match ip {
        IpAddr::V4(v4) => v4.is_loopback(),
        IpAddr::V6(v6) => {
            v6 == Ipv6Addr::LOCALHOST || v6.to_ipv4_mapped().is_some_and(|v4| v4.is_loopback())
        }
    }
}

/// This process's effective uid (from `/proc/self/status`).
pub fn own_uid() -> Option<u32> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("Uid:"))?;
    line.split_whitespace().nth(2)?.parse().ok()
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::net::{TcpListener, TcpStream};

    #[test]
    fn table_addresses_in_host_order() {
        let v4 = address("0100007F:1F90").unwrap();
        if cfg!(target_endian = "little") {
            assert_eq!(v4, "127.0.0.1:8080".parse().unwrap());
            let v6 = address("00000000000000000000000001000000:0050").unwrap();
            assert_eq!(v6, "[::1]:80".parse().unwrap());
        }
        assert!(same(
            "127.0.0.1:5".parse().unwrap(),
            "[::ffff:127.0.0.1]:5".parse().unwrap()
        ));
    }

    /// A connection this process makes to itself is found, owned by this process's user.
    #[test]
    fn the_owner_of_a_loopback_connection_is_this_user() {
        let listener = TcpListener::bind("127.0.0.1:0").unwrap();
        let _client = TcpStream::connect(listener.local_addr().unwrap()).unwrap();
        let (server_side, peer) = listener.accept().unwrap();
        let local = server_side.local_addr().unwrap();
        assert_eq!(uid_of(local, peer), own_uid());
        assert!(own_uid().is_some());
    }
}
