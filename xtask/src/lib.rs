//! The library half of `cargo xtask`. The sweep engine (configuration, points, seeds, the
//! worker pool and its schedule, point files, locks, resume and merge) is the crate
//! `mhe-sweep`, re-exported here under its old path so the tool's modules and tests keep
//! one name for it. The commands themselves are the binary (`src/main.rs`). Monte-Carlo
//! runs of any loop and their per-run metrics stay a library API of `closed-loop`
//! (`closed_loop::monte_carlo`).

pub use mhe_sweep as sweep_engine;
