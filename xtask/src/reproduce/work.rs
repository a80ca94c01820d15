//! What the console shows while the library works ([`mhe_report::Observer`]): the work
//! lines with `-v`, the analysis estimates, ρ_lin's progress, and each simulation's progress
//! bar. The work of a simulation and its limit are the library's ([`mhe_report::Work`]).

use std::io::IsTerminal;
use std::sync::Mutex;
use std::time::{Duration, Instant};

use closed_loop::scenario::Scenario;
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use iss_certificate::certificate::CertificateOptions;

use super::{Settings, numfmt};

/// A runtime shorter than this shows no progress line.
const QUIET_FOR: Duration = Duration::from_secs(2);
/// Interval of the plain progress lines when stderr is not a terminal.
const PLAIN_EVERY: Duration = Duration::from_secs(10);

/// The observer of one job: prints the work lines when live and verbose (`-v`), the
/// progress on stderr when live.
pub(super) struct Console {
    live: bool,
    verbose: bool,
    /// When ρ_lin's last progress line was printed (seconds into the phase).
    linear_last: Mutex<f64>,
    /// The running simulation's progress.
    simulation: Mutex<Option<Progress>>,
}

impl Console {
    pub(super) fn new(settings: &Settings) -> Self {
        Self {
            live: settings.live,
            verbose: settings.verbose,
            linear_last: Mutex::new(0.0),
            simulation: Mutex::new(None),
        }
    }
}

impl mhe_report::Observer for Console {
    fn line(&self, line: &str) {
        if self.live && self.verbose {
            outln!("{line}");
        }
    }

    fn certifying(
        &self,
        scenario: &Scenario,
        mpc: Option<&mpc_core::CondensedMpc>,
        opts: &CertificateOptions,
    ) {
        if self.live && self.verbose {
            super::budget_lines(scenario, mpc, opts);
        }
    }

    /// A line every 10 s once the analysis has run for 2 s.
    fn linear_progress(&self, done: usize, total: usize, t: f64) {
        if !self.live {
            return;
        }
        let Ok(mut last) = self.linear_last.lock() else {
            return;
        };
        if t >= 2.0 && t - *last >= 10.0 {
            *last = t;
            use std::io::Write;
            let _ = writeln!(
                std::io::stderr(),
                "  ρ_lin: {done}/{total} (method, K) eigenvalue problems done, {t:.0} s"
            );
        }
    }

    fn simulation_started(&self, label: &str, steps: usize) {
        if let Ok(mut p) = self.simulation.lock() {
            *p = Some(Progress::new(label.to_string(), steps, self.live));
        }
    }

    fn simulation_progress(&self, done: usize) {
        if let Ok(mut p) = self.simulation.lock() {
            if let Some(p) = p.as_mut() {
                p.update(done);
            }
        }
    }

    fn simulation_finished(&self) {
        if let Ok(mut p) = self.simulation.lock() {
            if let Some(p) = p.take() {
                p.finish();
            }
        }
    }
}

/// Progress of one simulation on stderr: nothing for the first [`QUIET_FOR`]; then a bar
/// when stderr is a terminal, else a plain line every [`PLAIN_EVERY`]. Never on stdout.
pub(super) struct Progress {
    enabled: bool,
    terminal: bool,
    label: String,
    steps: usize,
    start: Instant,
    last_plain: Instant,
    bar: Option<ProgressBar>,
}

impl Progress {
    /// Progress for `steps` steps labelled `label`; `enabled = false` shows nothing.
    pub(super) fn new(label: String, steps: usize, enabled: bool) -> Self {
        let now = Instant::now();
        Self {
            enabled,
            terminal: std::io::stderr().is_terminal(),
            label,
            steps,
            start: now,
            last_plain: now,
            bar: None,
        }
    }

    /// `done` of the steps are finished.
    pub(super) fn update(&mut self, done: usize) {
        if !self.enabled {
            return;
        }
        let elapsed = self.start.elapsed();
        if elapsed < QUIET_FOR {
            return;
        }
        if self.terminal {
            let bar = self.bar.get_or_insert_with(|| {
                let bar = ProgressBar::with_draw_target(
                    Some(self.steps as u64),
                    ProgressDrawTarget::stderr(),
                );
                if let Ok(style) = ProgressStyle::with_template(
                    "{msg} [{bar:30}] step {pos}/{len}, {elapsed} elapsed, ETA {eta}",
                ) {
                    bar.set_style(style);
                }
                bar.set_message(self.label.clone());
                bar
            });
            bar.set_position(done as u64);
        } else if self.last_plain.elapsed() >= PLAIN_EVERY && done < self.steps {
            // (The end is reported by the caller's "done in" line.)
            self.last_plain = Instant::now();
            let secs = elapsed.as_secs_f64();
            let left = if done > 0 {
                format!(
                    ", about {} s left",
                    numfmt::num(secs * (self.steps - done) as f64 / done as f64)
                )
            } else {
                String::new()
            };
            errln!(
                "  {}: step {done}/{} after {} s{left}",
                self.label,
                self.steps,
                numfmt::num(secs)
            );
        }
    }

    /// Removes the bar (the summary follows on stdout).
    pub(super) fn finish(self) {
        if let Some(bar) = self.bar {
            bar.finish_and_clear();
        }
    }
}
