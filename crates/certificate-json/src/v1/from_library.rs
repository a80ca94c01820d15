//! `From<&library type>` for the records of [`super::outcomes`].

mod gamma13_joint;
mod global_loop;
mod plant;
mod regional_ioss;
mod report;
mod theorem1;
