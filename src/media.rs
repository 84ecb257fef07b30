//! `vl media`: the Media between Guests and a Host, a relay that gives real
//! messages the delay, jitter, retransmissions and disconnects of a
//! modelled link; and `--link`, the same relay in front of `vl host` and
//! `vl demo`.

use std::net::SocketAddr;

use anyhow::{Context, Result};
use vl_core::Named;
use vl_host::{Media, MediaConfig};
use vl_sim::{LinkModel, Profile};

use crate::BadInput;
use crate::report::emit;

/// A modelled link to put in front of a lab.
#[derive(clap::Args)]
pub(crate) struct LinkArgs {
    /// Put a modelled Internet link between Guests and the lab: a profile
    /// (lan, internet2, internet-2005, intercontinental, congested,
    /// geo-satellite) or a JSON file of a link model.
    #[arg(long)]
    link: Option<String>,
    /// Seed for the link's random delays.
    #[arg(long, default_value_t = 1)]
    link_seed: u64,
}

impl LinkArgs {
    /// The link asked for, checked, if any.
    pub(crate) fn model(&self) -> Result<Option<LinkModel>> {
        self.link.as_deref().map(load).transpose()
    }

    /// Puts the link asked for in front of the Host at `upstream`, listening
    /// on `listen`; None when no link was asked for.
    pub(crate) async fn front(&self, listen: SocketAddr, upstream: &str) -> Result<Option<Media>> {
        let Some(model) = self.model()? else {
            return Ok(None);
        };
        let config = MediaConfig {
            upstream: upstream.to_owned(),
            model,
            seed: self.link_seed,
        };
        Ok(Some(
            Media::start(listen, config)
                .await
                .context("cannot start the Media")?,
        ))
    }
}

/// A link profile by name or file; a bad one is the user's input.
pub(crate) fn load(spec: &str) -> Result<LinkModel> {
    LinkModel::load(spec).map_err(|e| BadInput(format!("--link/--profile: {e}")).into())
}

/// `vl media`: relay, or measure the relay.
#[derive(clap::Args)]
#[command(args_conflicts_with_subcommands = true)]
pub(crate) struct MediaCommand {
    #[command(subcommand)]
    tool: Option<MediaTool>,
    #[command(flatten)]
    relay: MediaArgs,
}

#[derive(clap::Subcommand)]
enum MediaTool {
    /// Measure what the relay adds to a round trip by itself: an echo
    /// server's round trips straight and through a zero-delay relay, in turn.
    Bench {
        /// Round trips each way for the relay's own cost.
        #[arg(long, default_value_t = 5000, value_parser = clap::value_parser!(u64).range(1..=1_000_000))]
        messages: u64,
        /// Profiles to check the relay against its model on, comma-separated
        /// (names or files; default: every shipped one).
        #[arg(long, value_delimiter = ',')]
        profiles: Vec<String>,
        #[arg(long)]
        json: bool,
    },
}

pub(crate) async fn run(command: MediaCommand) -> Result<()> {
    match command.tool {
        Some(MediaTool::Bench {
            messages,
            profiles,
            json,
        }) => {
            let names: Vec<String> = if profiles.is_empty() {
                Profile::ALL.iter().map(|p| p.id().to_owned()).collect()
            } else {
                profiles
            };
            let links = names
                .iter()
                .map(|n| Ok((n.clone(), load(n)?)))
                .collect::<Result<Vec<_>>>()?;
            let bench = vl_host::media_bench(messages as usize, &links)
                .await
                .context("the relay bench failed")?;
            emit(&bench, json)
        }
        None => media(command.relay).await,
    }
}

#[derive(clap::Args)]
pub(crate) struct MediaArgs {
    /// Address Guests connect to; port 0 picks a free one.
    #[arg(long, default_value = "127.0.0.1:7401", value_parser = vl_core::listen_address)]
    listen: SocketAddr,
    /// The Host's WebSocket URL.
    #[arg(long, default_value = "ws://127.0.0.1:7400")]
    upstream: String,
    /// The link in each direction: a profile (lan, internet2, internet-2005,
    /// intercontinental, congested, geo-satellite) or a JSON file of a link model.
    #[arg(long, default_value = "lan")]
    profile: String,
    /// Seed for the link's random delays.
    #[arg(long, default_value_t = 1)]
    seed: u64,
}

async fn media(args: MediaArgs) -> Result<()> {
    let config = MediaConfig {
        upstream: args.upstream.clone(),
        model: load(&args.profile)?,
        seed: args.seed,
    };
    let media = Media::start(args.listen, config)
        .await
        .map_err(|e| match e {
            vl_host::MediaError::Upstream(_) => anyhow::Error::from(BadInput(e.to_string())),
            other => anyhow::Error::from(other).context("cannot start the Media"),
        })?;
    // Scripts and tests read the bound address from this first line.
    println!(
        "vl media listening on {} for {} through '{}'",
        media.url(),
        args.upstream,
        args.profile
    );
    tokio::select! {
        () = media.wait() => anyhow::bail!("the relay stopped"),
        signal = tokio::signal::ctrl_c() => {
            signal.context("cannot wait for Ctrl-C")?;
            Ok(())
        }
    }
}
