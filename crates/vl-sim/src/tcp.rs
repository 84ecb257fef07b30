//! A WebSocket's messages over the modelled link. WebSocket runs on TCP,
//! which delivers every message once and in order: a lost packet is not a
//! missing message but one that waits for its retransmission (and holds up
//! those behind it); a duplicate is dropped by the receiver; and a link
//! that stays down ends the connection. This is the model the Media relay
//! applies to real messages and the experiments' expectations are drawn from.

use std::path::Path;

use thiserror::Error;
use vl_core::Named;

use crate::link::{Link, LinkModel, Profile};

/// The first retransmission timeout, ms: Linux's minimum RTO.
pub const RTO_MS: f64 = 200.0;
/// Retransmissions before TCP gives up on the connection (the RTO doubles
/// each time; Linux's `tcp_retries2` is 15, but a lab's user gives up sooner).
const RETRIES: u32 = 8;

/// What became of one message.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Delivery {
    /// It arrives at this time, ms.
    At(f64),
    /// The link is down: the connection closes.
    Disconnected,
}

/// One direction of a TCP connection over a modelled link.
pub struct MessageLink {
    link: Link,
    /// When the previous message arrived: none may overtake it.
    last_arrival: f64,
}

impl MessageLink {
    pub fn new(model: LinkModel, seed: u64) -> MessageLink {
        MessageLink {
            link: Link::new(model, seed),
            last_arrival: f64::NEG_INFINITY,
        }
    }

    pub fn model(&self) -> &LinkModel {
        self.link.model()
    }

    /// Whether the link is down at `t_ms` (a scheduled disconnect).
    pub fn down(&self, t_ms: f64) -> bool {
        self.link
            .model()
            .disconnects
            .iter()
            .any(|&(a, b)| (a..b).contains(&t_ms))
    }

    /// Sends a message of `bytes` at `t_ms`: when it arrives, after any
    /// retransmissions and behind every earlier message.
    pub fn send(&mut self, t_ms: f64, bytes: usize) -> Delivery {
        let mut attempt = t_ms;
        let mut rto = RTO_MS;
        for retry in 0..=RETRIES {
            if self.down(attempt) {
                return Delivery::Disconnected;
            }
            let copies = if retry == 0 {
                self.link.send(attempt, bytes)
            } else {
                self.link.resend(attempt, bytes)
            };
            // The first copy to arrive is the one TCP keeps.
            let first = copies.into_iter().min_by(f64::total_cmp);
            if let Some(arrival) = first {
                let arrival = arrival.max(self.last_arrival);
                self.last_arrival = arrival;
                return Delivery::At(arrival);
            }
            attempt += rto;
            rto *= 2.0;
        }
        Delivery::Disconnected
    }
}

/// Why a link cannot be had.
#[derive(Debug, Error)]
pub enum LinkSpecError {
    #[error(
        "'{0}' is neither a link profile ({known}) nor a profile file",
        known = Profile::ALL.iter().map(|p| p.id()).collect::<Vec<_>>().join(", ")
    )]
    Unknown(String),
    #[error(
        "there is no file '{0}' (a link profile file; check the path), and no profile is named so ({known})",
        known = Profile::ALL.iter().map(|p| p.id()).collect::<Vec<_>>().join(", ")
    )]
    Missing(String),
    #[error("cannot read link profile {path}: {cause}")]
    Read { path: String, cause: String },
    #[error("link profile {path} is not a link model: {cause}")]
    Parse { path: String, cause: String },
    #[error("link profile {path}: {what}")]
    Invalid { path: String, what: String },
}

/// The longest one-way delay or disconnect a profile may ask for, ms.
const LONGEST_MS: f64 = 3_600_000.0;
/// The largest profile file read.
const PROFILE_BYTES: u64 = 1 << 20;

impl LinkModel {
    /// A shipped profile by name, or a JSON file of a `LinkModel`.
    pub fn load(spec: &str) -> Result<LinkModel, LinkSpecError> {
        if let Ok(profile) = spec.parse::<Profile>() {
            return Ok(LinkModel::profile(profile));
        }
        let path = Path::new(spec);
        if !path.is_file() {
            // A name with a dot or a slash was meant as a file.
            let meant_a_file = spec.contains(['.', '/', std::path::MAIN_SEPARATOR]);
            return Err(if meant_a_file {
                LinkSpecError::Missing(spec.to_owned())
            } else {
                LinkSpecError::Unknown(spec.to_owned())
            });
        }
        let read = |cause: String| LinkSpecError::Read {
            path: spec.to_owned(),
            cause,
        };
        let size = std::fs::metadata(path)
            .map_err(|e| read(e.to_string()))?
            .len();
        if size > PROFILE_BYTES {
            return Err(read(format!("{size} bytes is more than a profile needs")));
        }
        let text = std::fs::read_to_string(path).map_err(|e| read(e.to_string()))?;
        let model: LinkModel = serde_json::from_str(&text).map_err(|e| LinkSpecError::Parse {
            path: spec.to_owned(),
            cause: e.to_string(),
        })?;
        model.check().map_err(|what| LinkSpecError::Invalid {
            path: spec.to_owned(),
            what,
        })?;
        Ok(model)
    }

    /// Every number finite and in its range, so no delay is NaN or endless.
    fn check(&self) -> Result<(), String> {
        let ms = |name: &str, v: f64| {
            if (0.0..=LONGEST_MS).contains(&v) {
                Ok(())
            } else {
                Err(format!("{name} must be 0 to {LONGEST_MS} ms, not {v}"))
            }
        };
        let share = |name: &str, v: f64| {
            if (0.0..=1.0).contains(&v) {
                Ok(())
            } else {
                Err(format!("{name} must be 0 to 1, not {v}"))
            }
        };
        ms("delay_ms", self.delay_ms)?;
        ms("jitter_ms", self.jitter_ms)?;
        share("correlation", self.correlation)?;
        share("duplicate", self.duplicate)?;
        share("reorder", self.reorder)?;
        match self.loss {
            crate::Loss::None => {}
            crate::Loss::Random { p, correlation } => {
                share("loss p", p)?;
                share("loss correlation", correlation)?;
            }
            crate::Loss::GilbertElliott {
                p,
                r,
                bad_loss,
                good_loss,
            } => {
                share("loss p", p)?;
                share("loss r", r)?;
                share("bad_loss", bad_loss)?;
                share("good_loss", good_loss)?;
            }
        }
        if let Some(rate) = self.rate_bytes_s
            && !(rate.is_finite() && rate >= 1.0)
        {
            return Err(format!("rate_bytes_s must be at least 1, not {rate}"));
        }
        for &(a, b) in &self.disconnects {
            ms("a disconnect's start", a)?;
            ms("a disconnect's end", b)?;
            if b < a {
                return Err(format!(
                    "a disconnect ends ({b} ms) before it starts ({a} ms)"
                ));
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        /// Whatever the profile, messages arrive once, in order, never before they were sent.
        #[test]
        fn messages_arrive_in_order_and_never_early(
            profile in proptest::sample::select(Profile::ALL),
            seed in any::<u64>(),
            gaps in proptest::collection::vec(0.0f64..50.0, 1..300),
        ) {
            let mut link = MessageLink::new(LinkModel::profile(profile), seed);
            let mut t = 0.0;
            let mut last = f64::NEG_INFINITY;
            for gap in gaps {
                t += gap;
                match link.send(t, 200) {
                    Delivery::At(at) => {
                        prop_assert!(at >= t && at >= last);
                        last = at;
                    }
                    Delivery::Disconnected => prop_assert!(false, "no profile disconnects"),
                }
            }
        }
    }

    #[test]
    fn a_lost_packet_is_a_late_message() {
        let model = LinkModel {
            loss: crate::Loss::Random {
                p: 0.3,
                correlation: 0.0,
            },
            ..LinkModel::profile(Profile::Lan)
        };
        let mut link = MessageLink::new(model, 7);
        let late = (0..1000)
            .map(|i| match link.send(f64::from(i) * 1e5, 100) {
                Delivery::At(at) => at - f64::from(i) * 1e5,
                Delivery::Disconnected => panic!("a lossy link still delivers"),
            })
            .filter(|&d| d >= RTO_MS)
            .count();
        assert!((240..360).contains(&late), "{late} of 1000 retransmitted");
    }

    #[test]
    fn a_disconnect_closes() {
        let model = LinkModel {
            disconnects: vec![(100.0, 200.0)],
            ..LinkModel::profile(Profile::Lan)
        };
        let mut link = MessageLink::new(model, 1);
        assert!(matches!(link.send(50.0, 10), Delivery::At(_)));
        assert_eq!(link.send(150.0, 10), Delivery::Disconnected);
        assert!(matches!(link.send(250.0, 10), Delivery::At(_)));
    }

    #[test]
    fn profiles_load_by_name_or_file_and_bad_ones_are_named() {
        assert_eq!(
            LinkModel::load("lan").unwrap(),
            LinkModel::profile(Profile::Lan)
        );
        let e = LinkModel::load("dialup").unwrap_err().to_string();
        assert!(
            e.contains("'dialup' is neither") && e.contains("geo-satellite"),
            "{e}"
        );
        let dir = std::env::temp_dir().join(format!("vl-link-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let file = dir.join("p.json");
        let good = serde_json::to_string(&LinkModel {
            disconnects: vec![(5000.0, 8000.0)],
            ..LinkModel::profile(Profile::Intercontinental)
        })
        .unwrap();
        std::fs::write(&file, &good).unwrap();
        let spec = file.to_str().unwrap();
        assert_eq!(
            LinkModel::load(spec).unwrap().disconnects,
            vec![(5000.0, 8000.0)]
        );
        std::fs::write(
            &file,
            good.replace("\"delay_ms\":75.0", "\"delay_ms\":-1.0"),
        )
        .unwrap();
        let e = LinkModel::load(spec).unwrap_err().to_string();
        assert!(e.contains("delay_ms must be 0"), "{e}");
        std::fs::write(&file, "{\"delay_ms\": 1}").unwrap();
        let e = LinkModel::load(spec).unwrap_err().to_string();
        assert!(e.contains("is not a link model"), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
