//! What `reproduce` runs: the presets, a job (scenario and output directory), the
//! sampling and search settings, and the jobs of a command line.

use super::*;

/// The t of Fig. 2(c) when `--fig2c-t` is not given: 6 for the presets (the paper's), else
/// M + 1 (the first step whose window is full and whose prior is the scheme's own estimate;
/// 6 for the paper's M = 5), within the simulated steps.
pub fn default_fig2c_t(preset: Option<Preset>, scenario: &Scenario) -> usize {
    let last = scenario.simulation.steps.saturating_sub(1);
    match (preset, &scenario.mhe) {
        (Some(_), _) | (None, None) => FIG2C_T.min(last),
        (None, Some(m)) => (m.horizon() + 1).min(last),
    }
}

/// The shipped case-study scenarios.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Preset {
    /// The paper's M = 5, η = 0.8, K = 652 (certificate void: 6·0.8⁵ ≥ 1).
    Paper,
    /// The nearest parameters satisfying every premise (M = 9), simulated at K_min.
    Certified,
}

impl Preset {
    /// Both presets, in the order `reproduce` runs them.
    pub const ALL: [Preset; 2] = [Preset::Paper, Preset::Certified];

    /// `"paper"` or `"certified"` (also the output subdirectory).
    pub fn name(self) -> &'static str {
        match self {
            Preset::Paper => "paper",
            Preset::Certified => "certified",
        }
    }

    /// The scenario file, relative to the workspace root.
    pub fn scenario_file(self) -> &'static str {
        match self {
            Preset::Paper => "scenarios/case-study.toml",
            Preset::Certified => "scenarios/case-study-certified.toml",
        }
    }

    /// A job for this preset writing into `out_root/<name>`.
    pub fn job(self, out_root: &Path) -> Job {
        Job {
            label: self.name().to_string(),
            preset: Some(self),
            scenario: workspace_root().join(self.scenario_file()),
            out: out_root.join(self.name()),
        }
    }
}

/// One scenario to reproduce and where its files go.
#[derive(Debug, Clone, PartialEq)]
pub struct Job {
    /// Name used in the outputs (`"paper"`, `"certified"`, or the file stem).
    pub label: String,
    /// The preset, if the scenario is one.
    pub preset: Option<Preset>,
    /// Scenario file.
    pub scenario: PathBuf,
    /// Output directory (created).
    pub out: PathBuf,
}

/// Sampling and search settings (defaults: those of the shipped results).
#[derive(Debug, Clone, PartialEq)]
pub struct Settings {
    /// Random pairs of the sampled L_Φ and L_π.
    pub lipschitz_pairs: usize,
    /// Injected error sequences per magnitude for the sampled γ₁,₃ (0 skips it).
    pub gamma13_sequences: usize,
    /// Cap on N·n_u for the free-set enumerations (γ₁,₃, L_π).
    pub enumeration_max_vars: usize,
    /// γ₁,₃ from the certified enumeration or supplied.
    pub gamma13: Gamma13Source,
    /// Largest K searched for K_min.
    pub k_max: usize,
    /// The small K simulated next to the scenario's K when the certificate is void.
    pub small_k: usize,
    /// Write the SVG figures.
    pub figures: bool,
    /// The t of Fig. 2(c) (`--fig2c-t`); None: [`default_fig2c_t`].
    pub fig2c_t: Option<usize>,
    /// Show progress on stderr, and with [`Settings::verbose`] print each work line when it
    /// happens (stdout); the lines are in [`Outcome::log`] and summary.md either way.
    pub live: bool,
    /// `-v`: print the work lines, the analysis estimates and the long summary (the
    /// default prints the screen summary only; summary.md has everything either way).
    pub verbose: bool,
    /// `--sim-k-cap`: the largest computed K_min that is simulated (None: no cap beyond the
    /// work limit).
    pub sim_k_cap: Option<usize>,
}

impl Default for Settings {
    fn default() -> Self {
        Self {
            lipschitz_pairs: 200,
            gamma13_sequences: 30,
            enumeration_max_vars: 20,
            gamma13: Gamma13Source::Certified,
            k_max: 1 << 24,
            small_k: 5,
            figures: true,
            fig2c_t: None,
            live: false,
            verbose: false,
            sim_k_cap: None,
        }
    }
}

impl Settings {
    /// The library's options of these settings (the work lines named `label`).
    pub(super) fn options(&self, label: &str) -> mhe_report::Options {
        mhe_report::Options {
            label: label.to_string(),
            lipschitz_pairs: self.lipschitz_pairs,
            gamma13_sequences: self.gamma13_sequences,
            enumeration_max_vars: self.enumeration_max_vars,
            gamma13: self.gamma13,
            k_max: self.k_max,
            small_k: self.small_k,
            sim_k_cap: self.sim_k_cap,
            threads: None,
        }
    }
}

/// The jobs of a command line: one preset, a user scenario, or both presets (default).
pub fn jobs(preset: Option<Preset>, scenario: Option<PathBuf>, out: Option<PathBuf>) -> Vec<Job> {
    let out = out.unwrap_or_else(|| workspace_root().join("target/reproduce"));
    match (preset, scenario) {
        (_, Some(path)) => {
            let label = path.file_stem().map_or_else(
                || "scenario".to_string(),
                |s| s.to_string_lossy().into_owned(),
            );
            vec![Job {
                out: out.join(&label),
                label,
                preset: None,
                scenario: path,
            }]
        }
        (Some(p), None) => vec![p.job(&out)],
        (None, None) => Preset::ALL.iter().map(|p| p.job(&out)).collect(),
    }
}
