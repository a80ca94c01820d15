//! The certified estimator of the case study as C sources, from Rust: K is K_min of
//! Theorem 1, refused if the verdict does not certify it. Run from the workspace root:
//! `cargo run --release -p mhe-export --example export_c [OUT_DIR]`.

use closed_loop::scenario::Scenario;
use mhe_export::{ExportOptions, Lang, Source, export};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let path = "scenarios/case-study-certified.toml";
    let resolved = Scenario::from_file(path)?.resolve()?;
    let mut options = ExportOptions::default(); // method of the scenario, K certified, f64
    options.lang = Lang::C;
    options.source = Source::from_bytes(path, &std::fs::read(path)?);
    let artefact = export(&resolved, &options)?;
    let out = std::env::args()
        .nth(1)
        .unwrap_or_else(|| "target/mhe-export-c".into());
    artefact.write_to(out.as_ref())?;
    println!(
        "{} with K = {} (K_min = {:?}), certified: {}; written to {out}",
        artefact.method(),
        artefact.k(),
        artefact.k_min(),
        artefact.loop_certified()
    );
    Ok(())
}
