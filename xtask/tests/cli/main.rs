//! xtask's integration tests that link the tool, in one test binary: one link of the whole
//! tool instead of eleven, and one process whose threads pick up the next module's tests
//! while a slow test runs (docs/testing.md, "Test times"). Each module was a binary of its
//! own and is unchanged: `cargo test -p xtask --test cli MODULE::` runs one of them.
//! `public_api` (the API snapshot) and `survey` (the dishonesty survey) stay binaries of
//! their own, under the names CI and the docs use.

#[path = "../generate/mod.rs"]
mod generate;

mod engine;
mod export_cli;
mod generated_cli;
mod generated_inputs;
mod golden;
mod hardening_cli;
mod one_truth_cli;
mod plants_cli;
mod reproduce_cli;
mod shared;
mod sweep_cli;
mod terminal_digits;
#[path = "../../src/test_dir.rs"]
mod test_dir;
