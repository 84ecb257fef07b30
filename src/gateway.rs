//! `vl gateway`: the lab's one public address in front of many cells
//! (`vl host --gateway … --cell NAME`), on Zenoh.

use std::net::SocketAddr;
use std::time::Duration;

use anyhow::{Context, Result, bail};
use vl_host::{Endpoint, Gateway, HostConfig};

use crate::access::AccessArgs;

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
}

#[derive(clap::Args)]
pub(crate) struct GatewayArgs {
    /// Address for Guests and browsers; port 0 picks a free one.
    #[arg(long, default_value = "127.0.0.1:7400", value_parser = vl_core::listen_address)]
    listen: SocketAddr,
    /// The Zenoh network its cells meet it on.
    #[command(flatten)]
    zenoh: crate::options::ZenohArgs,
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
        None => gateway(command.serve).await,
    }
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
        ..HostConfig::default()
    };
    args.access.apply(&mut config)?;
    let zenoh = args.zenoh.options();
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
                "vl gateway: cells join with `vl host --gateway {} --cell NAME`",
                at.join(" --gateway ")
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
