//! The command-line flags `hps-sim` and `hps-linux` share, which mean the
//! same in both (so scripts and tests move between the two), and starting
//! the camera and the page as they say.

use std::net::{Ipv4Addr, SocketAddr};

use rt_services::camera::sender::Multicast;

use crate::rtsp::Options;
use crate::Server;

/// The camera's and the page's flags.
#[derive(clap::Args, Debug, Clone)]
pub struct ServiceArgs {
    /// Address of the RTSP server (the board as a network camera; RTP and
    /// RTCP leave from two free UDP ports). Default: the listen address
    /// with port 8554.
    #[arg(long)]
    pub rtsp: Option<SocketAddr>,
    /// The first multicast group streams set up with
    /// `Transport: RTP/AVP;multicast` go to (without one, such a SETUP is
    /// answered 461): stream `i` of the camera goes to this address plus
    /// `i`, on `--multicast-port`; the server joins each group it sends to
    /// and hears RTCP on the next port.
    #[arg(long)]
    pub multicast_group: Option<Ipv4Addr>,
    /// The multicast groups' RTP port (RTCP: the next one).
    #[arg(long, default_value_t = 5006)]
    pub multicast_port: u16,
    /// The multicast packets' time to live (1: they stay on the link).
    #[arg(long, default_value_t = 1)]
    pub multicast_ttl: u8,
    /// Address of the board's web page (port 80 on the board; below 1024
    /// needs root or CAP_NET_BIND_SERVICE): the live picture in a browser,
    /// the light under the mouse.
    #[arg(long)]
    pub http: Option<SocketAddr>,
}

/// Where the camera and the page listen, once started.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Started {
    /// The RTSP server.
    pub rtsp: SocketAddr,
    /// The page, if asked for.
    pub http: Option<SocketAddr>,
}

impl ServiceArgs {
    /// The multicast streams' destination, if a group was given; an error
    /// naming the flag if it is not a multicast address.
    pub fn multicast(&self) -> Result<Option<Multicast>, String> {
        match self.multicast_group {
            Some(group) if !group.is_multicast() => {
                Err("--multicast-group must be a multicast address (224.0.0.0/4)".into())
            }
            Some(group) => Ok(Some(Multicast { group, base_port: self.multicast_port, ttl: self.multicast_ttl })),
            None => Ok(None),
        }
    }

    /// Start the camera (on `--rtsp`, or the `listen` address's IP with
    /// port 8554) with `options` (their multicast from these flags) and
    /// the page when `--http` is given, on `sim`.
    pub fn start(&self, sim: &mut Server, listen: SocketAddr, options: Options) -> Result<Started, String> {
        let options = Options { multicast: self.multicast()?, ..options };
        let rtsp = self.rtsp.unwrap_or(SocketAddr::new(listen.ip(), rt_services::camera::rtsp::RTSP_PORT));
        let rtsp = sim.start_rtsp_with(rtsp, options).map_err(|e| format!("cannot serve RTSP on {rtsp}: {e}"))?;
        let http = match self.http {
            Some(http) => Some(
                sim.start_web(http, options.verbose)
                    .map_err(|e| format!("cannot serve the web page on {http}: {e}"))?,
            ),
            None => None,
        };
        Ok(Started { rtsp, http })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn args(group: Option<Ipv4Addr>) -> ServiceArgs {
        ServiceArgs { rtsp: None, multicast_group: group, multicast_port: 5006, multicast_ttl: 1, http: None }
    }

    #[test]
    fn only_a_multicast_group_is_taken() {
        assert_eq!(args(None).multicast(), Ok(None));
        let m = args(Some(Ipv4Addr::new(239, 255, 42, 1))).multicast().unwrap().unwrap();
        assert_eq!((m.group, m.base_port, m.ttl), (Ipv4Addr::new(239, 255, 42, 1), 5006, 1));
        assert!(args(Some(Ipv4Addr::new(10, 0, 0, 1))).multicast().unwrap_err().contains("224.0.0.0/4"));
    }
}
