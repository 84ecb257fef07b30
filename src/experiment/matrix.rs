//! `vl experiment report`: the whole matrix of links × experiments ×
//! pacing × seeds, with its progress on the console; `vl_campaign`
//! runs it and writes the report.

use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;

use anyhow::{Context, Result};
use clap::Args;
use vl_campaign::{Matrix, cells_of, progress_line, run_all, write_report};
use vl_core::Named;

use crate::named::{ExperimentChoice, ExperimentChoiceParser, offered};
use vl_sim::{LinkModel, Profile};

use crate::input::{load_arena, seconds};
use crate::report::emit;

#[derive(Args)]
pub(crate) struct ReportArgs {
    /// Where to write report.md, report.json and the plots.
    #[arg(long)]
    out: PathBuf,
    /// The experiments, comma-separated: each a cell per link (those
    /// driven by stick two: paced by event and by time). Ids, and folders
    /// whose experiments are served beside the shipped ones (all of them
    /// measured when no id is named).
    #[arg(
        long,
        value_delimiter = ',',
        value_parser = ExperimentChoiceParser,
        default_value = "navigation,teleoperation",
        value_hint = clap::ValueHint::AnyPath
    )]
    experiments: Vec<ExperimentChoice>,
    /// Seeds per cell (profile × experiment × pacing).
    #[arg(long, default_value_t = 5, value_parser = clap::value_parser!(u64).range(1..=100))]
    seeds: u64,
    /// The first seed.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Link profiles, comma-separated (default: every shipped one).
    #[arg(long, value_delimiter = ',')]
    profiles: Vec<String>,
    /// The arena every run drives in.
    #[arg(long, default_value = "navigation")]
    arena: String,
    /// Runs at once (each is a lab, a relay and a Guest).
    #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u64).range(1..=16))]
    jobs: u64,
    /// Give up on a run after this many seconds.
    #[arg(long, default_value_t = 120.0)]
    timeout: f64,
    /// Print the summary as JSON (report.json is written either way).
    #[arg(long)]
    json: bool,
}

pub(crate) fn report(runtime: &tokio::runtime::Runtime, args: ReportArgs) -> Result<ExitCode> {
    let timeout = seconds("--timeout", args.timeout)?;
    let names: Vec<String> = if args.profiles.is_empty() {
        Profile::ALL.iter().map(|p| p.id().to_owned()).collect()
    } else {
        args.profiles.clone()
    };
    let links: Vec<(String, LinkModel)> = names
        .iter()
        .map(|n| Ok((n.clone(), crate::media::load(n)?)))
        .collect::<Result<_>>()?;
    let arena = load_arena(&args.arena)?;
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("cannot create {}", args.out.display()))?;
    let seeds = args.seed..args.seed + args.seeds;
    let lab = offered(&args.experiments)?;
    let specs = cells_of(&lab, &links, &arena, seeds, timeout);
    let total = specs.len();
    let started = Instant::now();
    eprintln!(
        "vl experiment report: {total} runs ({} profiles × navigation, teleoperation event, teleoperation time × {} seeds), {} at a time",
        links.len(),
        args.seeds,
        args.jobs
    );
    let runs = runtime.block_on(run_all(specs, args.jobs as usize, |finished, run| {
        eprintln!(
            "[{finished}/{total}] {:.0} s  {} {} {}: {}",
            started.elapsed().as_secs_f64(),
            run.experiment,
            run.profile.as_deref().unwrap_or("loopback"),
            run.pacing,
            progress_line(run)
        );
    }))?;
    let matrix = Matrix::of(
        &names,
        args.seeds,
        &arena.name,
        started.elapsed().as_secs_f64(),
        runs,
    );
    write_report(&args.out, &matrix, &arena)?;
    emit(&matrix, args.json)?;
    if !args.json {
        println!(
            "wrote {} and {}",
            args.out.join("report.md").display(),
            args.out.join("report.json").display()
        );
    }
    Ok(
        if matrix.event_based_synchronised && matrix.collisions == 0 {
            ExitCode::SUCCESS
        } else {
            ExitCode::FAILURE
        },
    )
}
