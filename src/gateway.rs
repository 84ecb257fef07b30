//! `vl gateway`: the lab's one public address in front of many cells
//! (`vl host --gateway … --cell NAME`), on Zenoh.

use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Duration;

use anyhow::{Context, Result, bail};
use vl_cells::{Endpoint, Gateway, ZenohAuthority, ZenohMember, ZenohTrust};
use vl_host::HostConfig;

use crate::access::AccessArgs;
use crate::{BadInput, bad_input};

#[derive(clap::Args)]
#[command(args_conflicts_with_subcommands = true)]
pub(crate) struct GatewayCommand {
    #[command(subcommand)]
    tool: Option<GatewayTool>,
    #[command(flatten)]
    serve: GatewayArgs,
}

#[derive(clap::Subcommand)]
enum GatewayTool {
    /// What a gateway adds and saves: simulated cells (processes of their
    /// own), an operator on each straight to its cell and through the
    /// gateway, and watchers through the gateway; command → feedback, each
    /// process's processor, the gateway's bytes out.
    Bench {
        #[arg(long, default_value_t = 16, value_parser = clap::value_parser!(u64).range(1..=64))]
        cells: u64,
        /// Guests watching through the gateway, spread over the cells.
        #[arg(long, default_value_t = 500, value_parser = clap::value_parser!(u64).range(0..=4000))]
        watchers: u64,
        /// Commands each operator times in each round.
        #[arg(long, default_value_t = 500, value_parser = clap::value_parser!(u64).range(1..=1_000_000))]
        commands: u64,
        #[arg(long)]
        json: bool,
    },
    /// Lets a cell or a ROS 2 machine onto the gateway's Zenoh network:
    /// writes its credentials (a certificate the gateway's authority signs,
    /// and its key) to hand to that machine. The gateway admits it from its
    /// next start.
    Issue {
        #[command(flatten)]
        member: MemberArgs,
        /// Where to write the credentials (default: NAME.toml here).
        #[arg(long, short)]
        out: Option<PathBuf>,
        #[command(flatten)]
        keys: KeysArgs,
    },
    /// Whom the gateway's network admits.
    Members {
        #[command(flatten)]
        keys: KeysArgs,
        #[arg(long)]
        json: bool,
    },
    /// Takes a member off the network: from the gateway's next start its
    /// certificate may do nothing there.
    Revoke {
        #[command(flatten)]
        member: MemberArgs,
        #[command(flatten)]
        keys: KeysArgs,
    },
}

/// One member of the gateway's Zenoh network.
#[derive(clap::Args)]
#[group(required = true, multiple = false)]
struct MemberArgs {
    /// A cell, by the name it joins with (`vl host --cell NAME`).
    #[arg(long, value_name = "NAME")]
    cell: Option<vl_core::CellName>,
    /// A ROS 2 machine (rviz, a teleop, a robot's base), by a name of
    /// your choosing: it speaks ROS 2 there, never the lab's own keys.
    #[arg(long, value_name = "NAME")]
    ros2: Option<vl_core::CellName>,
}

impl MemberArgs {
    /// The member named (clap asks for exactly one of the two).
    fn member(&self) -> Result<ZenohMember> {
        match (&self.cell, &self.ros2) {
            (Some(cell), _) => Ok(ZenohMember::Cell(cell.clone())),
            (None, Some(name)) => Ok(ZenohMember::Ros2(name.clone())),
            (None, None) => bail!(BadInput("give --cell NAME or --ros2 NAME".into())),
        }
    }
}

/// Where the gateway keeps its authority.
#[derive(clap::Args)]
struct KeysArgs {
    /// The folder of the gateway's certificate authority and its members
    /// (default: vl/gateway in the data directory).
    #[arg(long, value_name = "DIR")]
    keys: Option<PathBuf>,
}

impl KeysArgs {
    fn authority(&self) -> Result<ZenohAuthority> {
        let dir = match &self.keys {
            Some(dir) => dir.clone(),
            None => vl_record::data_dir()
                .context("no data directory: give --keys DIR")?
                .join("gateway"),
        };
        ZenohAuthority::open(&dir).map_err(|e| anyhow::Error::new(bad_input(e)))
    }
}

#[derive(clap::Args)]
pub(crate) struct GatewayArgs {
    /// Address for Guests and browsers; port 0 picks a free one.
    #[arg(long, default_value = "127.0.0.1:7400", value_parser = vl_core::listen_address)]
    listen: SocketAddr,
    /// The Zenoh network its cells meet it on.
    #[command(flatten)]
    zenoh: crate::options::ZenohArgs,
    /// A host name or address cells reach the gateway's Zenoh router by,
    /// beyond those it listens on and this machine's name: its
    /// certificate must name it.
    #[arg(long, value_name = "HOST")]
    zenoh_name: Vec<String>,
    /// The ROS 2 domain its cells' ROS 2 sides use (`vl host --ros2`).
    #[arg(long, default_value = "0")]
    ros2_domain: u32,
    #[command(flatten)]
    keys: KeysArgs,
    /// A client the gateway hears nothing from this long is disconnected.
    #[arg(long, default_value = "10", value_parser = crate::duration)]
    ping_timeout: Duration,
    #[command(flatten)]
    access: AccessArgs,
}

pub(crate) async fn gateway_command(command: GatewayCommand) -> Result<()> {
    match command.tool {
        Some(GatewayTool::Bench {
            cells,
            watchers,
            commands,
            json,
        }) => {
            raise_file_limit();
            let bench = vl_host::GatewayBench {
                cells: cells as usize,
                watchers: watchers as usize,
                commands: commands as usize,
            };
            let vl = std::env::current_exe().context("cannot find the vl binary")?;
            let cost = bench.run(&vl).await.context("the gateway bench failed")?;
            crate::report::emit(&cost, json)
        }
        Some(GatewayTool::Issue { member, out, keys }) => {
            let member = member.member()?;
            let name = match &member {
                ZenohMember::Cell(name) | ZenohMember::Ros2(name) => name,
            };
            let out = out.unwrap_or_else(|| PathBuf::from(format!("{name}.toml")));
            issue(&keys.authority()?, member, &out)
        }
        Some(GatewayTool::Members { keys, json }) => {
            let members = keys.authority()?.members().map_err(bad_input)?;
            if json {
                println!("{}", serde_json::to_string_pretty(&members)?);
            } else if members.is_empty() {
                println!("no members: `vl gateway issue --cell NAME` lets a cell join");
            } else {
                members.iter().for_each(|m| println!("{m}"));
            }
            Ok(())
        }
        Some(GatewayTool::Revoke { member, keys }) => {
            let member = member.member()?;
            keys.authority()?.revoke(&member).map_err(bad_input)?;
            println!("{member} revoked: restart the gateway for it to take effect");
            Ok(())
        }
        None => gateway(command.serve).await,
    }
}

/// Issues `member`'s credentials to `out` and says how to use them.
fn issue(authority: &ZenohAuthority, member: ZenohMember, out: &Path) -> Result<()> {
    if out.exists() {
        bail!(BadInput(format!(
            "{} exists: give another --out, or remove it first",
            out.display()
        )));
    }
    let credentials = authority.issue(member.clone()).map_err(bad_input)?;
    credentials.save(out).map_err(bad_input)?;
    println!(
        "{member}'s credentials are in {} (its private key: copy it to that machine only, e.g. with scp)",
        out.display()
    );
    match &member {
        ZenohMember::Cell(name) => println!(
            "on the cell: vl host --gateway quic/GATEWAY:7447 --cell {name} --zenoh-credentials {}",
            out.display()
        ),
        ZenohMember::Ros2(_) => println!(
            "on the ROS 2 machine: a Zenoh session config with transport/link/tls (enable_mtls) from this file, connecting to quic/GATEWAY:7447"
        ),
    }
    println!("a running gateway admits it from its next start");
    Ok(())
}

/// The names the gateway's router certificate holds: where it listens
/// (this machine's names, for an address of every interface), and those
/// given.
fn router_names(zenoh: &vl_cells::ZenohOptions, given: &[String]) -> Vec<String> {
    let mut names: Vec<String> = ["localhost", "127.0.0.1", "::1"].map(String::from).to_vec();
    for endpoint in &zenoh.listen {
        let host = endpoint.host();
        if host
            .parse::<std::net::IpAddr>()
            .is_ok_and(|ip| ip.is_unspecified())
        {
            names.extend(hostname());
        } else {
            names.push(host.to_owned());
        }
    }
    names.extend(given.iter().cloned());
    names.sort();
    names.dedup();
    names
}

/// This machine's host name.
fn hostname() -> Option<String> {
    let name = std::fs::read_to_string("/proc/sys/kernel/hostname").ok()?;
    let name = name.trim();
    (!name.is_empty()).then(|| name.to_owned())
}

/// A gateway holds a socket for each of its Guests (thousands): the
/// soft limit on open files is raised to the hard one.
fn raise_file_limit() {
    let mut limit = libc::rlimit {
        rlim_cur: 0,
        rlim_max: 0,
    };
    // SAFETY: getrlimit and setrlimit read and write the struct given.
    unsafe {
        if libc::getrlimit(libc::RLIMIT_NOFILE, &mut limit) == 0 && limit.rlim_cur < limit.rlim_max
        {
            limit.rlim_cur = limit.rlim_max;
            libc::setrlimit(libc::RLIMIT_NOFILE, &limit);
        }
    }
}

async fn gateway(args: GatewayArgs) -> Result<()> {
    raise_file_limit();
    let mut config = HostConfig {
        ping_timeout: args.ping_timeout,
        // Foxglove's server tells a client at the gateway to go to a
        // cell's own Host, rather than leaving it unanswered.
        extensions: crate::host::plugs::always(),
        ..HostConfig::default()
    };
    args.access.apply(&mut config)?;
    let mut zenoh = args.zenoh.options(args.listen, true)?;
    let mut members = Vec::new();
    if zenoh.connect.is_empty() {
        // Its own router: only the members its authority issued to join.
        let authority = args.keys.authority()?;
        let router = authority
            .router(router_names(&zenoh, &args.zenoh_name), args.ros2_domain)
            .map_err(bad_input)?;
        members = authority.members().map_err(bad_input)?;
        zenoh.trust = ZenohTrust::Router(Arc::new(router));
    }
    let gateway = Gateway::start(args.listen, config, zenoh.clone())
        .await
        .context("the gateway cannot start")?;
    // Scripts and tests read the bound address from this first line.
    println!("vl gateway listening on ws://{}", gateway.addr);
    match zenoh.connect.first() {
        Some(network) => eprintln!("vl gateway: cells meet it on the Zenoh network at {network}"),
        None => {
            let at: Vec<String> = zenoh.listen.iter().map(Endpoint::to_string).collect();
            eprintln!(
                "vl gateway: cells join with `vl host --gateway {} --cell NAME --zenoh-credentials FILE` (FILE from `vl gateway issue --cell NAME`)",
                at.join(" --gateway ")
            );
            let members: Vec<String> = members.iter().map(ToString::to_string).collect();
            eprintln!(
                "vl gateway: its Zenoh network admits {}",
                if members.is_empty() {
                    "no one yet".to_owned()
                } else {
                    members.join(", ")
                }
            );
        }
    }
    let mut terminate = tokio::signal::unix::signal(tokio::signal::unix::SignalKind::terminate())
        .context("cannot wait for SIGTERM")?;
    tokio::select! {
        () = gateway.wait() => bail!("the gateway stopped (see the log above)"),
        signal = tokio::signal::ctrl_c() => signal.context("cannot wait for Ctrl-C")?,
        _ = terminate.recv() => {}
    }
    eprintln!("vl gateway: stopping");
    Ok(())
}
