//! The iteration-budget grids of a sweep config: `k` (K = K_e, the MHE's) and `k_c` (K_c,
//! the sub-optimal MPC's, in a 2-D sweep), each a list of integers or a log-spaced range
//! `{ from, to, points }`, validated against [`MAX_K`] with errors naming the key.

use std::fmt;

use serde::Deserialize;
use serde::de::{self, MapAccess, SeqAccess, Visitor};

use super::config::MAX_K;
use super::error::{Result, config_err};

use iss_certificate::linear::log_spaced;

/// `k` or `k_c`: a list of budgets, or a log-spaced range.
#[derive(Debug)]
pub(super) enum RawK {
    List(Vec<i64>),
    Range(RawRange),
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawRange {
    from: Option<i64>,
    to: Option<i64>,
    points: Option<i64>,
}

// A list or a table, told apart by the TOML value itself; the elements and keys are read
// through the access objects serde_path_to_error hands in, so their paths are recorded.
impl<'de> Deserialize<'de> for RawK {
    fn deserialize<D: de::Deserializer<'de>>(d: D) -> std::result::Result<Self, D::Error> {
        struct KVisitor;
        impl<'de> Visitor<'de> for KVisitor {
            type Value = RawK;
            fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                f.write_str("a list of integers `[1, 10, 100]` or a table `{ from, to, points }`")
            }
            fn visit_seq<A: SeqAccess<'de>>(
                self,
                mut seq: A,
            ) -> std::result::Result<RawK, A::Error> {
                let mut list = Vec::new();
                while let Some(k) = seq.next_element::<i64>()? {
                    list.push(k);
                }
                Ok(RawK::List(list))
            }
            fn visit_map<A: MapAccess<'de>>(self, map: A) -> std::result::Result<RawK, A::Error> {
                RawRange::deserialize(de::value::MapAccessDeserializer::new(map)).map(RawK::Range)
            }
        }
        d.deserialize_any(KVisitor)
    }
}

/// An integer key with 1 ≤ value ≤ `max`.
pub(super) fn positive(value: i64, key: &str, max: usize) -> Result<usize> {
    if value < 1 {
        return Err(config_err(key, format!("must be ≥ 1, got {value}")));
    }
    match usize::try_from(value) {
        Ok(u) if u <= max => Ok(u),
        _ => Err(config_err(key, format!("must be ≤ {max}, got {value}"))),
    }
}

pub(super) fn k_grid(raw: Option<RawK>) -> Result<Vec<usize>> {
    let raw = raw.ok_or_else(|| {
        config_err(
            "k",
            "missing: give a list `k = [1, 10, 100]` or a log-spaced range `k = { from = 1, to = 2000, points = 12 }`",
        )
    })?;
    budget_grid(
        raw,
        "k",
        "K",
        "the K grid is empty; list at least one K ≥ 1",
    )
}

/// The grid of a budget key (`k`, `k_c`): a list of integers in 1..=[`MAX_K`], or a
/// log-spaced range; sorted, duplicates removed. `what` names the budget in messages.
fn budget_grid(raw: RawK, key: &str, what: &str, empty: &str) -> Result<Vec<usize>> {
    let mut grid = match raw {
        RawK::List(list) => {
            if list.is_empty() {
                return Err(config_err(key, empty));
            }
            list.iter()
                .enumerate()
                .map(|(i, &k)| {
                    usize::try_from(k)
                        .ok()
                        .filter(|&k| (1..=MAX_K).contains(&k))
                        .ok_or_else(|| {
                            config_err(
                                format!("{key}[{i}]"),
                                format!(
                                    "{what} = {k} is out of range: the iteration budget must be 1 ≤ {what} ≤ {MAX_K}"
                                ),
                            )
                        })
                })
                .collect::<Result<Vec<_>>>()?
        }
        RawK::Range(r) => {
            let req = |v: Option<i64>, sub: &str| -> Result<usize> {
                let name = format!("{key}.{sub}");
                let v = v.ok_or_else(|| {
                    config_err(
                        &*name,
                        format!("missing (a {what} range needs from, to, points ≥ 1)"),
                    )
                })?;
                positive(v, &name, MAX_K)
            };
            let from = req(r.from, "from")?;
            let to = req(r.to, "to")?;
            let points = req(r.points, "points")?;
            if to < from {
                return Err(config_err(
                    format!("{key}.to"),
                    format!("must be ≥ {key}.from = {from}, got {to}"),
                ));
            }
            log_spaced(from, to, points)
        }
    };
    grid.sort_unstable();
    grid.dedup();
    Ok(grid)
}

/// `k_c`: the K_c grid of a 2-D sweep (None: a 1-D sweep).
pub(super) fn k_c_grid(raw: Option<RawK>) -> Result<Option<Vec<usize>>> {
    raw.map(|raw| {
        budget_grid(
            raw,
            "k_c",
            "K_c",
            "the K_c grid is empty; list at least one K_c ≥ 1, or remove k_c for a sweep over K alone",
        )
    })
    .transpose()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn log_spacing_is_geometric() {
        let g = log_spaced(1, 2000, 16);
        assert_eq!(g.first(), Some(&1));
        assert_eq!(g.last(), Some(&2000));
        // Ratios of consecutive values stay near (2000)^(1/15) ≈ 1.66 once rounding stops mattering.
        for w in g.windows(2).filter(|w| w[0] >= 20) {
            let r = w[1] as f64 / w[0] as f64;
            assert!((r - 2000f64.powf(1.0 / 15.0)).abs() < 0.1, "{w:?}");
        }
    }
}
