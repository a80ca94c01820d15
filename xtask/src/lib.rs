//! The library half of `cargo xtask`: the sweep engine (configuration, points, seeds, the
//! worker pool and its schedule, point files, locks, resume and merge). The commands
//! themselves are the binary (`src/main.rs`). Monte-Carlo runs of any loop and their
//! per-run metrics stay a library API of `closed-loop` (`closed_loop::monte_carlo`).

pub mod sweep_engine;
