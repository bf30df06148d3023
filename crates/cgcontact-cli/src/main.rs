//! `cgcontact`: locate contact points in deformed cartesian-lattice meshes (cgFEM).
//!
//! Exit codes: 0 success; 2 bad input or any other error, with one line on stderr naming the file
//! and the line, cell or node at fault.
#![forbid(unsafe_code)]

mod demo;
mod locate;
mod picture;
mod run;
mod scene;
mod tradeoff;

use std::process::ExitCode;

use clap::{Parser, Subcommand};

/// Contact search for the Cartesian grid Finite Element Method: which deformed hexahedron holds each
/// point, and at which local coordinates ξ ∈ [−1, 1]³.
#[derive(Parser, Debug)]
#[command(
    name = "cgcontact",
    version,
    propagate_version = true,
    after_help = "Examples:
  cgcontact demo --out demo-out
  cgcontact scene sphere-fine --out scene
  cgcontact locate --mesh scene/mesh.vtu --points scene/points.csv --out results.csv --json"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    Demo(demo::DemoArgs),
    Locate(locate::LocateArgs),
    Scene(scene::SceneArgs),
    Tradeoff(tradeoff::TradeoffArgs),
}

fn main() -> ExitCode {
    // A bug must still end in one line, not a trace: say where, and exit like other errors.
    std::panic::set_hook(Box::new(|info| {
        eprintln!("cgcontact: internal error (please report): {info}");
    }));
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Demo(args) => demo::run(&args),
        Command::Locate(args) => locate::run(&args),
        Command::Scene(args) => scene::run(&args),
        Command::Tradeoff(args) => tradeoff::run(&args),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(error) => {
            // One line: the chain of causes joined, the file and line/cell named by the innermost.
            eprintln!("cgcontact: error: {error:#}");
            ExitCode::from(2)
        }
    }
}
