#![doc = include_str!("../README.md")]
//!
//! ## Contents
//!
//! - [`v1`]: version 1 of both documents — [`v1::Certificate`] (`certificate.json` of
//!   `cargo xtask reproduce`, format [`v1::CERTIFICATE_FORMAT`]) and [`v1::IossCertificate`]
//!   (the JSON of `cargo xtask certify`, format [`v1::IOSS_FORMAT`]) — and the records of the
//!   library outcomes they embed, each with a `From<&library type>` conversion (the case
//!   study's report: `From<&mhe_report::…>`); and `trace.json` ([`v1::TraceDocument`],
//!   format [`v1::TRACE_FORMAT`]), built by [`v1::TraceDocument::new`] from a report's runs.

pub mod v1;
