//! `From<&library type>` for the records of [`super::outcomes`].

mod gamma13_joint;
mod plant;
mod global_loop;
mod regional_ioss;
mod report;
mod theorem1;
