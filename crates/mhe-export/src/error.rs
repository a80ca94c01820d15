//! The export's one error type: what went wrong, the option it concerns and the fix.

use std::path::{Path, PathBuf};

/// Why [`export`](crate::export) or [`Artefact::write_to`](crate::Artefact::write_to)
/// failed. Every message names the option (the CLI flag `--k`, `--kc`, `--method`,
/// `--mpc-method`, `--prefix`, `--out`; the [`ExportOptions`](crate::ExportOptions) field of
/// the same name, `k_c` for `--kc`) and the fix. Options are checked before any work.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ExportError {
    /// An option is invalid (checked before any work).
    #[error("{message}")]
    InvalidOption {
        /// The [`ExportOptions`](crate::ExportOptions) field (`k`, `k_c`, `prefix`, …).
        option: &'static str,
        /// What is wrong and the fix, naming the CLI flag.
        message: String,
    },
    /// The scenario lacks what the options ask for (an `[mhe]` section, an `[mpc]` section
    /// for `k_c`).
    #[error("{message}")]
    Scenario {
        /// What is missing and the fix.
        message: String,
    },
    /// A certificate (Theorem 1, the closed loop's, the joint MPC + MHE one) could not be
    /// computed.
    #[error("{message}")]
    Certificate {
        /// The certificate's error.
        message: String,
    },
    /// K (`option` = `k`) or K_c (`k_c`) is not certified and `allow_uncertified` is false.
    #[error("{message}")]
    NotCertified {
        /// `k` or `k_c`.
        option: &'static str,
        /// The verdict, the certified floor when there is one, and the fix.
        message: String,
    },
    /// The estimator's or the MPC's numbers cannot be exported (a method or warm start the
    /// embedded code does not implement).
    #[error("{message}")]
    Unsupported {
        /// What the embedded code lacks.
        message: String,
    },
    /// The output directory is refused, or writing it failed (nothing was replaced then).
    #[error("{message}")]
    Output {
        /// The output directory.
        path: PathBuf,
        /// What happened and the fix.
        message: String,
    },
}

impl ExportError {
    /// The whole chain of an internal error (`anyhow`'s `{:#}`), as the CLI prints it.
    fn chain(e: &anyhow::Error) -> String {
        format!("{e:#}")
    }

    pub(crate) fn option(option: &'static str, e: &anyhow::Error) -> Self {
        Self::InvalidOption {
            option,
            message: Self::chain(e),
        }
    }

    pub(crate) fn certificate(e: &anyhow::Error) -> Self {
        Self::Certificate {
            message: Self::chain(e),
        }
    }

    pub(crate) fn not_certified(option: &'static str, e: &anyhow::Error) -> Self {
        Self::NotCertified {
            option,
            message: Self::chain(e),
        }
    }

    pub(crate) fn unsupported(e: &anyhow::Error) -> Self {
        Self::Unsupported {
            message: Self::chain(e),
        }
    }

    pub(crate) fn output(path: &Path, e: &anyhow::Error) -> Self {
        Self::Output {
            path: path.to_path_buf(),
            message: Self::chain(e),
        }
    }
}
