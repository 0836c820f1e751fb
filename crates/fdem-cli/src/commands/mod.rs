//! One module per subcommand.

pub mod coarsen;
pub mod compare;
pub mod mesh;
pub mod micro;
pub mod progress;
pub mod run;
pub mod scale;
pub mod specimen;
pub mod stability;
pub mod study;
pub mod triaxial;

use anyhow::{Context, bail};

/// Output format shared by the subcommands that print results.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Format {
    /// Human-readable table.
    #[default]
    Table,
    /// One JSON object on stdout.
    Json,
}

/// Parses a strictly positive, finite number given on the command line as `flag`.
pub fn positive_number(flag: &str, text: &str) -> anyhow::Result<f64> {
    let value: f64 = text
        .trim()
        .parse()
        .ok()
        .with_context(|| format!("{flag} must be a positive number, got '{text}'"))?;
    if !value.is_finite() || value <= 0.0 {
        bail!("{flag} must be a positive finite number, got '{text}'");
    }
    Ok(value)
}

/// The most worker threads `--threads` accepts: beyond any machine this code targets, and
/// low enough that a typo does not spawn thousands of threads.
pub const MAX_THREADS: usize = 1024;

/// Runs a command on a worker of the global pool, with `--threads` workers (all cores
/// when it is not given).
///
/// A thread outside the pool that opens a parallel region hands the work over and sleeps
/// on a lock until it is done, at every region; a time step opens several. On a worker,
/// a region is a push onto its own queue that the others steal from, and the worker takes
/// part in the work (docs/PERFORMANCE.md, "One team for the whole run, and the lane kernel").
pub fn on_pool<T: Send>(
    threads: Option<usize>,
    command: impl FnOnce() -> anyhow::Result<T> + Send,
) -> anyhow::Result<T> {
    set_threads(threads)?;
    rayon::scope(|_| command())
}

/// Sets the number of worker threads of the global pool from `--threads` (all cores when
/// it is not given).
fn set_threads(threads: Option<usize>) -> anyhow::Result<()> {
    if let Some(threads) = threads {
        anyhow::ensure!(threads > 0, "--threads must be at least 1");
        anyhow::ensure!(
            threads <= MAX_THREADS,
            "--threads {threads} is more than {MAX_THREADS}; give at most the machine's cores (or leave it out for all of them)"
        );
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build_global()
            .context("setting up the thread pool")?;
    }
    Ok(())
}

/// How long after the first interrupt further ones count as the same one: `timeout -s INT`
/// and a terminal both may deliver one signal to the process and to its group at once.
const INTERRUPT_GRACE: std::time::Duration = std::time::Duration::from_secs(2);

/// A flag that Ctrl-C, SIGTERM or SIGHUP sets: the long loops check it, stop, and finish
/// their outputs with an `interrupted` summary. A second interrupt more than
/// [`INTERRUPT_GRACE`] after the first exits at once (status 130), removing the
/// temporaries of the unfinished outputs.
pub fn interrupt_flag() -> std::sync::Arc<std::sync::atomic::AtomicBool> {
    use std::sync::atomic::{AtomicBool, Ordering};
    use std::sync::{Arc, Mutex, PoisonError};
    let flag = Arc::new(AtomicBool::new(false));
    let set = Arc::clone(&flag);
    let first: Mutex<Option<std::time::Instant>> = Mutex::new(None);
    // Without a handler (one is already installed) the default action stays: the
    // process ends at the signal, as before any handler.
    let _ = ctrlc::set_handler(move || {
        let mut first = first.lock().unwrap_or_else(PoisonError::into_inner);
        match *first {
            None => {
                *first = Some(std::time::Instant::now());
                set.store(true, Ordering::SeqCst);
                eprintln!(
                    "interrupted: finishing the outputs (interrupt again after {} s to exit at once)",
                    INTERRUPT_GRACE.as_secs()
                );
            }
            Some(t) if t.elapsed() >= INTERRUPT_GRACE => {
                // Exiting runs no destructors: the unfinished outputs go here.
                fdem_core::fs::remove_unfinished();
                std::process::exit(130)
            }
            Some(_) => {}
        }
    });
    flag
}

/// Checks before any long work that `dir` can hold outputs: it is (or can be created as)
/// a directory in which a file can be written.
pub fn check_output_dir(dir: &std::path::Path) -> anyhow::Result<()> {
    if dir.exists() && !dir.is_dir() {
        bail!(
            "--out {} is a file, not a directory; give a directory for the outputs",
            dir.display()
        );
    }
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let probe = dir.join(".fdem-write-check.part");
    std::fs::write(&probe, b"").with_context(|| {
        format!(
            "{} cannot be written to; give a writable --out directory",
            dir.display()
        )
    })?;
    let _ = std::fs::remove_file(&probe);
    Ok(())
}

/// Checks before any long work that the file `path` can be written: not a directory,
/// and its directory (created if missing) writable.
pub fn check_output_file(path: &std::path::Path) -> anyhow::Result<()> {
    if path.is_dir() {
        bail!(
            "--out {} is a directory; give the path of the file to write",
            path.display()
        );
    }
    match path.parent().filter(|p| !p.as_os_str().is_empty()) {
        Some(parent) => check_output_dir(parent),
        None => check_output_dir(std::path::Path::new(".")),
    }
}

/// Writes a scene to `path` atomically, with a header comment saying where it came from.
pub fn write_scene(
    scene: &fdem_solver::Scene,
    path: &std::path::Path,
    origin: &str,
) -> anyhow::Result<()> {
    let text = format!(
        "# Generated by fdem: {origin}.\n{}",
        scene.to_toml_string()?
    );
    fdem_core::fs::write_atomically(path, text)
        .with_context(|| format!("writing {}", path.display()))
}

/// Prints the factor applied to each field, as a table or JSON.
pub fn print_applied(applied: &[fdem_solver::Applied], format: Format) -> anyhow::Result<()> {
    match format {
        Format::Json => {
            let fields: Vec<serde_json::Value> = applied
                .iter()
                .map(|(key, quantity, factor)| {
                    serde_json::json!({"key": key, "quantity": quantity, "factor": factor})
                })
                .collect();
            println!(
                "{}",
                serde_json::to_string_pretty(&serde_json::json!({ "fields": fields }))?
            );
        }
        Format::Table => {
            println!("{:<36} {:<20} {:>14}", "key", "quantity", "factor");
            for (key, quantity, factor) in applied {
                println!("{key:<36} {quantity:<20} {factor:>14}");
            }
        }
    }
    Ok(())
}

/// The command line as a generated document names it: `name` (the `--invoked-as` text,
/// else `default`) and the arguments after the subcommand, without `--invoked-as`.
pub fn command_line(invoked_as: Option<&str>, default: &str) -> String {
    let mut words: Vec<String> = Vec::new();
    let mut skip = false;
    for w in std::env::args().skip(2) {
        if std::mem::take(&mut skip) {
            continue;
        }
        if w == "--invoked-as" {
            skip = true;
            continue;
        }
        if !w.starts_with("--invoked-as=") {
            words.push(w);
        }
    }
    format!("{} {}", invoked_as.unwrap_or(default), words.join(" "))
        .trim_end()
        .to_string()
}
