//! The SVG plots of an assembled sweep (feature `plots`), drawn from its `points.csv` with
//! `mhe-plots`: band charts over K for a 1-D sweep ([`band_charts`]), heat maps over
//! (K_e, K_c) with the region boundaries for a 2-D sweep ([`heat_maps`]). The same bytes as
//! `cargo xtask sweep` writes; each function returns (file name, SVG text) and writes nothing.
//!
//! ```no_run
//! use mhe_sweep::{Sweep, SweepConfig, Table, plots};
//!
//! let sweep = Sweep::new(SweepConfig::from_file("sweeps/smoke.toml")?)?;
//! // The points.csv of a finished run of that sweep (`Sweep::run`, or `cargo xtask sweep`).
//! let table = Table::parse(&std::fs::read_to_string("target/sweeps/smoke/points.csv")?)?;
//! for (name, svg) in plots::draw(&sweep, &table, &[])? {
//!     std::fs::write(name, svg)?;
//! }
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! `cargo run -p mhe-sweep --features plots --example first_sweep` draws the plots of a
//! small sweep.

mod band;
mod heat;

pub use band::band_charts;
pub use heat::heat_maps;
pub use mhe_plots::PlotError;

use crate::{PairThresholds, Sweep, Table};

/// The plots of an assembled sweep: heat maps for a 2-D sweep (`pairs` carry the
/// boundaries, [`pair_thresholds`](crate::pair_thresholds)), band charts over K for a 1-D
/// one (`pairs` unused). (file name, SVG text) per plot, in the order the tool writes them.
pub fn draw(
    sweep: &Sweep,
    table: &Table,
    pairs: &[PairThresholds],
) -> Result<Vec<(String, String)>, PlotError> {
    if sweep.config().is_2d() {
        heat_maps(sweep, table, pairs)
    } else {
        band_charts(sweep, table)
    }
}
