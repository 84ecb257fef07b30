//! `vl sim …`: the simulator's tools.

use std::process::ExitCode;

use anyhow::Result;
use clap::Subcommand;
use serde::Serialize;
use vl_sim::link::{Link, LinkModel, LinkStats, measure};

use crate::BadInput;

#[derive(Subcommand)]
pub enum SimCommand {
    /// Send packets through a modelled link and measure what they went through.
    Link {
        /// lan, internet2, internet-2005, intercontinental, congested or geo-satellite.
        #[arg(long)]
        profile: String,
        #[arg(long, default_value_t = 100_000)]
        packets: usize,
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// Milliseconds between packets.
        #[arg(long, default_value_t = 10.0)]
        interval_ms: f64,
        #[arg(long)]
        json: bool,
    },
}

pub fn run(command: SimCommand) -> Result<ExitCode> {
    match command {
        SimCommand::Link {
            profile,
            packets,
            seed,
            interval_ms,
            json,
        } => link(&profile, packets, seed, interval_ms, json),
    }
}

/// Measured figures beside the ones the profile asks for.
#[derive(Serialize)]
struct LinkReport {
    profile: String,
    model: LinkModel,
    measured: LinkStats,
    expected: Expected,
}

#[derive(Serialize)]
struct Expected {
    delay_mean_ms: f64,
    jitter_ms: f64,
    loss_rate: f64,
    mean_loss_burst: f64,
}

fn link(
    profile: &str,
    packets: usize,
    seed: u64,
    interval_ms: f64,
    json: bool,
) -> Result<ExitCode> {
    let model = LinkModel::profile(profile).map_err(|e| BadInput(e.to_string()))?;
    let expected = Expected {
        delay_mean_ms: model.expected_delay(),
        jitter_ms: model.expected_jitter(),
        loss_rate: model.expected_loss(),
        mean_loss_burst: model.expected_burst(),
    };
    let mut link = Link::new(model.clone(), seed);
    let measured = measure(&mut link, packets, interval_ms, 100);
    if json {
        let report = LinkReport {
            profile: profile.to_owned(),
            model,
            measured,
            expected,
        };
        println!("{}", serde_json::to_string_pretty(&report)?);
        return Ok(ExitCode::SUCCESS);
    }
    let m = &measured;
    println!("{profile}: {packets} packets, one every {interval_ms} ms, seed {seed}");
    println!("{:<18} {:>12} {:>12}", "", "measured", "profile");
    let rows = [
        ("delay mean, ms", m.delay_mean_ms, expected.delay_mean_ms),
        ("jitter (sd), ms", m.jitter_ms, expected.jitter_ms),
        (
            "loss rate, %",
            m.loss_rate * 100.0,
            expected.loss_rate * 100.0,
        ),
        ("loss burst", m.mean_loss_burst, expected.mean_loss_burst),
    ];
    for (name, got, want) in rows {
        println!("{name:<18} {got:>12.4} {want:>12.4}");
    }
    println!("{:<18} {:>12.3}", "delay p50, ms", m.delay_p50_ms);
    println!("{:<18} {:>12.3}", "delay p99, ms", m.delay_p99_ms);
    println!("{:<18} {:>12}", "duplicates", m.duplicates);
    println!("{:<18} {:>12}", "reorders", m.reorders);
    Ok(ExitCode::SUCCESS)
}
