//! Where Guests on other machines reach a Host: a Host listening on every
//! interface (`0.0.0.0`, `[::]`) is reached at each of this machine's
//! addresses, which it prints so a teacher can hand one out.

use std::net::{IpAddr, SocketAddr};

/// The addresses Guests can use for a Host bound to `bound`: itself, or
/// for an unspecified address each address of this machine of the same
/// family, those other machines can use first and loopback last.
pub(crate) fn reachable(bound: SocketAddr) -> Vec<SocketAddr> {
    if !bound.ip().is_unspecified() {
        return vec![bound];
    }
    let mut ips: Vec<IpAddr> = interface_addresses()
        .into_iter()
        .filter(|ip| ip.is_ipv4() == bound.is_ipv4())
        .filter(|ip| !is_link_local(ip))
        .collect();
    ips.sort_by_key(|ip| (ip.is_loopback(), *ip));
    ips.dedup();
    ips.into_iter()
        .map(|ip| SocketAddr::new(ip, bound.port()))
        .collect()
}

/// IPv6 link-local addresses need a zone to be dialled: not handed out.
fn is_link_local(ip: &IpAddr) -> bool {
    match ip {
        IpAddr::V4(v4) => v4.is_link_local(),
        IpAddr::V6(v6) => (v6.segments()[0] & 0xffc0) == 0xfe80,
    }
}

/// This machine's interface addresses, as the kernel lists them.
#[cfg(target_os = "linux")]
fn interface_addresses() -> Vec<IpAddr> {
    let mut found = Vec::new();
    let mut list: *mut libc::ifaddrs = std::ptr::null_mut();
    // SAFETY: getifaddrs fills `list` with a linked list it allocates,
    // which is walked read-only and freed once with freeifaddrs.
    unsafe {
        if libc::getifaddrs(&mut list) != 0 {
            return found;
        }
        let mut at = list;
        while !at.is_null() {
            let addr = (*at).ifa_addr;
            if !addr.is_null() {
                match i32::from((*addr).sa_family) {
                    libc::AF_INET => {
                        let v4 = &*(addr as *const libc::sockaddr_in);
                        found.push(IpAddr::from(u32::from_be(v4.sin_addr.s_addr).to_be_bytes()));
                    }
                    libc::AF_INET6 => {
                        let v6 = &*(addr as *const libc::sockaddr_in6);
                        found.push(IpAddr::from(v6.sin6_addr.s6_addr));
                    }
                    _ => {}
                }
            }
            at = (*at).ifa_next;
        }
        libc::freeifaddrs(list);
    }
    found
}

#[cfg(not(target_os = "linux"))]
fn interface_addresses() -> Vec<IpAddr> {
    vec![IpAddr::from([127, 0, 0, 1])]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_host_on_every_interface_is_reached_at_each_and_loopback_last() {
        let bound: SocketAddr = "127.0.0.1:7400".parse().unwrap();
        assert_eq!(reachable(bound), vec![bound]);
        let all = reachable("0.0.0.0:7400".parse().unwrap());
        assert!(
            all.iter().all(|a| a.is_ipv4() && a.port() == 7400),
            "{all:?}"
        );
        assert_eq!(
            all.last().map(|a| a.ip()),
            Some(IpAddr::from([127, 0, 0, 1])),
            "{all:?}"
        );
        assert!(all.iter().all(|a| !a.ip().is_unspecified()), "{all:?}");
    }
}
