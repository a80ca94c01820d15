//! The f32 certificates against 200 closed-loop seeds each (issue 36) and, for the global
//! certificate, against an optimised adversary (adversary.rs): every shipped scenario/method
//! pair certified in f32 (`cargo xtask export --survey`), at its certified f32 K, with
//! `mhe_embedded` in f32 in the loop. Run by .ci/run in release
//! (`cargo test --release -p iss-certificate --test loop_level -- --ignored`).
#![allow(dead_code)] // tests/all uses data.rs alone

mod adversary;
pub mod data;
mod global;
mod theorem1;

use closed_loop::scenario::{ResolvedScenario, Scenario};

/// A shipped scenario, resolved.
fn scenario(file: &str) -> ResolvedScenario {
    let path = format!("{}/../../scenarios/{file}", env!("CARGO_MANIFEST_DIR"));
    Scenario::from_file(&path)
        .expect("scenario parses")
        .resolve()
        .expect("resolves")
}
