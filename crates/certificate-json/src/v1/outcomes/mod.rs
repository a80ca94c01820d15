//! The library outcomes of version 1: one record per library outcome type, field order
//! = key order (written from the library types by a script, then reviewed). One file per
//! part of the certificate.

pub(crate) use super::Method;

mod gamma13_joint;
mod global_loop;
mod regional_ioss;
mod theorem1;

pub use gamma13_joint::*;
pub use global_loop::*;
pub use regional_ioss::*;
pub use theorem1::*;
