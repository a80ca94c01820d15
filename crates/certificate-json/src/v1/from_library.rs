//! `From<&library type>` for the records of [`super::outcomes`].

mod gamma13_joint;
mod global_loop;
mod regional_ioss;
mod theorem1;
