//! Shared fixtures for the criterion benchmarks (filled by the `qp-iter` issue).
