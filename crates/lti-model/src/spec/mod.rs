//! Scenario-file pieces owned by the ground floor: the format shared by every layer's
//! settings ([`mod@format`]) and the plant-level sections ([`plant`]). The scenario file that
//! composes them with the MHE and MPC settings is `closed_loop::scenario::Scenario`
//! (format: `docs/scenario-format.md`).

pub mod format;
pub mod limits;
pub mod names;
pub mod plant;

pub use format::{Bounds, MAX_DIMENSION, MatrixSpec, Table, key_error};
pub use plant::{DEFAULT_STEPS, NoiseKind, NoiseSpec, ScenarioSets, SimulationSpec};
