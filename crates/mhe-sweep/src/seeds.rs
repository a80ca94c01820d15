//! Which run gets which disturbance seed, and which shard runs which point: functions of
//! the configuration only, so results depend neither on threads nor on shards nor on order.

use std::fmt;
use std::str::FromStr;

use super::config::Point;
use super::error::{Result, SweepError};

pub use closed_loop::monte_carlo::splitmix64;

/// 64-bit FNV-1a of bytes (stable across platforms and Rust versions, unlike std's hasher).
pub(super) fn fnv1a(bytes: &[u8]) -> u64 {
    bytes.iter().fold(0xcbf2_9ce4_8422_2325, |h, &b| {
        (h ^ u64::from(b)).wrapping_mul(0x0000_0100_0000_01b3)
    })
}

/// The seed of run `run` at `point`: a function of (base seed, point, run index) only, so
/// results do not depend on threads, shards or order. With `common_random_numbers` the
/// point is ignored (same draw for run r at every point); otherwise the point enters as
/// FNV-1a of `"K/solver/scale bits"` (`"K/solver/scale bits/K_c"` in a 2-D sweep).
///
/// ```
/// use mhe_sweep::{run_seed, SweepConfig};
/// let cfg = SweepConfig::from_toml_str(
///     "name='d'\nscenario='s'\nk=[1,2]\nsolvers=['pg']\nseeds=2", std::path::Path::new(".")).unwrap();
/// let p = cfg.points();
/// assert_eq!(run_seed(7, &p[0], 1, true), run_seed(7, &p[1], 1, true));
/// assert_ne!(run_seed(7, &p[0], 1, false), run_seed(7, &p[1], 1, false));
/// assert_ne!(run_seed(7, &p[0], 0, true), run_seed(7, &p[0], 1, true));
/// ```
pub fn run_seed(base_seed: u64, point: &Point, run: usize, common_random_numbers: bool) -> u64 {
    let stream = if common_random_numbers {
        0
    } else {
        let mut key = format!("{}/{}/{}", point.k, point.solver, point.scale.to_bits());
        if let Some(k_c) = point.k_c {
            // 2-D sweeps only: a 1-D point's key is the one seeds were first drawn with.
            key.push_str(&format!("/{k_c}"));
        }
        fnv1a(key.as_bytes())
    };
    splitmix64(splitmix64(base_seed ^ splitmix64(stream)) ^ run as u64)
}

/// Shard I of N (1-based): the points with `index % N == I − 1`, so every shard gets a
/// mix of cheap and expensive K.
///
/// ```
/// use mhe_sweep::Shard;
/// let s: Shard = "2/4".parse().unwrap();
/// assert!(s.owns(1) && s.owns(5) && !s.owns(2));
/// assert!("3/2".parse::<Shard>().is_err());
/// assert!("0/2".parse::<Shard>().is_err());
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Shard {
    /// I, 1 ≤ I ≤ N.
    pub index: usize,
    /// N ≥ 1.
    pub count: usize,
}

impl Shard {
    /// Whether point `index` belongs to this shard.
    pub fn owns(&self, index: usize) -> bool {
        index % self.count == self.index - 1
    }
}

impl fmt::Display for Shard {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}/{}", self.index, self.count)
    }
}

impl FromStr for Shard {
    type Err = SweepError;
    fn from_str(spec: &str) -> Result<Self> {
        let err = |problem: &str| SweepError::Shard {
            spec: spec.to_string(),
            problem: problem.to_string(),
        };
        let (i, n) = spec.split_once('/').ok_or_else(|| err("no `/`"))?;
        let i: usize = i
            .trim()
            .parse()
            .map_err(|_| err("I is not a non-negative integer"))?;
        let n: usize = n
            .trim()
            .parse()
            .map_err(|_| err("N is not a non-negative integer"))?;
        if n == 0 {
            return Err(err("N = 0"));
        }
        if i == 0 {
            return Err(err("I = 0 (shards are numbered from 1)"));
        }
        if i > n {
            return Err(err("I > N"));
        }
        Ok(Self { index: i, count: n })
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use crate::SweepConfig;

    #[test]
    fn shards_partition_the_points() {
        for n in 1..6 {
            for idx in 0..40 {
                let owners = (1..=n)
                    .filter(|&i| Shard { index: i, count: n }.owns(idx))
                    .count();
                assert_eq!(owners, 1);
            }
        }
        for bad in ["3/2", "0/1", "1/0", "a/2", "2", "-1/2"] {
            assert!(
                matches!(bad.parse::<Shard>(), Err(SweepError::Shard { .. })),
                "{bad}"
            );
        }
    }

    #[test]
    fn seeds_are_distinct_and_stable() {
        let c = SweepConfig::from_toml_str(
            "name = 'x'\nscenario = 's.toml'\nsolvers = ['pg']\nseeds = 2\nk = [1, 2, 3]",
            std::path::Path::new("/base"),
        )
        .unwrap();
        let p = c.points();
        let mut seen = std::collections::HashSet::new();
        for q in &p {
            for r in 0..100 {
                seen.insert(run_seed(11, q, r, false));
            }
        }
        assert_eq!(seen.len(), 300);
        // A 1-D point's stream is FNV-1a of "K/solver/scale bits", as seeds were first drawn
        // (a 2-D point appends "/K_c").
        let want = |key: &str| splitmix64(splitmix64(11 ^ splitmix64(fnv1a(key.as_bytes()))) ^ 7);
        let bits = 1f64.to_bits();
        assert_eq!(run_seed(11, &p[1], 7, false), want(&format!("2/pg/{bits}")));
        let two_d = crate::Point {
            k_c: Some(5),
            ..p[1]
        };
        assert_eq!(
            run_seed(11, &two_d, 7, false),
            want(&format!("2/pg/{bits}/5"))
        );
        // A fixed value guards against accidental changes of the seed function (which
        // would silently change every published sweep).
        assert_eq!(splitmix64(0), 0xE220_A839_7B1D_CDAF);
    }
}
