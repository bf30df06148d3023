//! `cgcontact`: locate contact points in deformed cartesian-lattice meshes (cgFEM).
//!
//! Exit codes: 0 success; 2 bad input or any other error, with one line on stderr naming the file
//! and the line, cell or node at fault.
// Safe Rust, but for `oom`: the allocator that turns a failed allocation into exit code 2.
#![deny(unsafe_code)]

mod demo;
mod locate;
mod oom;
mod output;
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

/// The system's allocator, ending the run with one line and exit code 2 when it fails.
#[global_allocator]
static ALLOCATOR: oom::ExitOnOom = oom::ExitOnOom;

/// The exit code of a run ended by Ctrl-C or SIGTERM: 128 + SIGINT's number, as shells report.
const INTERRUPTED: i32 = 130;

fn main() -> ExitCode {
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(error) => return parse_error(&error),
    };
    // Panics print nothing by themselves: the I/O crate catches the VTK parser's panics on malformed
    // files and turns them into errors, and a bug of ours must still end in one line, not a trace.
    std::panic::set_hook(Box::new(|_| {}));
    // Ctrl-C or SIGTERM: no hidden temporary file is left beside an output; every output is as it
    // was or complete. Without the handler (it could not be set), the signal's default applies.
    let _ = ctrlc::set_handler(|| {
        cgcontact_io::abandon_writes();
        output::remove_made_folders();
        eprintln!("cgcontact: interrupted; outputs not yet complete were left as they were");
        std::process::exit(INTERRUPTED);
    });
    let result = std::panic::catch_unwind(|| match cli.command {
        Command::Demo(args) => demo::run(&args),
        Command::Locate(args) => locate::run(&args),
        Command::Scene(args) => scene::run(&args),
        Command::Tradeoff(args) => tradeoff::run(&args),
    });
    match result {
        Ok(Ok(())) => ExitCode::SUCCESS,
        Ok(Err(error))
            if error
                .downcast_ref::<output::StdoutError>()
                .is_some_and(output::StdoutError::is_closed_pipe) =>
        {
            // The reader went away (`| head`): a normal end, as for any Unix tool.
            ExitCode::SUCCESS
        }
        Ok(Err(error)) => {
            // One line: the chain of causes joined, the file and line/cell named by the innermost.
            eprintln!("cgcontact: error: {error:#}");
            ExitCode::from(2)
        }
        Err(payload) => {
            let message = payload
                .downcast_ref::<String>()
                .map(String::as_str)
                .or_else(|| payload.downcast_ref::<&str>().copied())
                .unwrap_or("unknown panic");
            eprintln!("cgcontact: internal error (please report it): {message}");
            ExitCode::from(2)
        }
    }
}

/// `--help` and `--version` print as clap writes them; a usage error becomes one line (clap's
/// message, the possible values, no blank line or hint) and exit code 2.
fn parse_error(error: &clap::Error) -> ExitCode {
    use clap::error::ErrorKind;
    if matches!(
        error.kind(),
        ErrorKind::DisplayHelp
            | ErrorKind::DisplayVersion
            | ErrorKind::DisplayHelpOnMissingArgumentOrSubcommand
    ) {
        // Printing help can only fail on a closed stdout, where there is no one left to tell.
        let _ = error.print();
        return if error.kind() == ErrorKind::DisplayHelpOnMissingArgumentOrSubcommand {
            ExitCode::from(2)
        } else {
            ExitCode::SUCCESS
        };
    }
    let rendered = error.render().to_string();
    let line: Vec<&str> = rendered
        .lines()
        .map(str::trim)
        .filter(|l| {
            !l.is_empty() && !l.starts_with("For more information") && !l.starts_with("Usage:")
        })
        .collect();
    let line = line.join(" ");
    eprintln!(
        "cgcontact: {}",
        line.strip_prefix("error: ")
            .map_or(line.clone(), |l| format!("error: {l}"))
    );
    ExitCode::from(2)
}

#[cfg(test)]
mod tests {
    use clap::CommandFactory;

    use super::Cli;

    /// The help's defaults are the library's (`Settings`), not copies that could drift.
    #[test]
    fn help_states_the_library_defaults() {
        use cgcontact::Settings;
        let mut cli = Cli::command();
        let locate = cli
            .find_subcommand_mut("locate")
            .expect("locate")
            .render_long_help();
        let help = locate.to_string();
        let tol = format!(
            "default: {:e} in f64, {:e} in f32",
            Settings::NEWTON_TOL,
            Settings::NEWTON_TOL_F32
        );
        assert!(help.contains(&tol), "{tol} not in the help");
        assert!(help.contains(&format!("[default: {}]", Settings::MAX_ITER)));
    }
}
