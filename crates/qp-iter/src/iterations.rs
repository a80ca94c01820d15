//! [`Iterations`]: an iteration budget K (of the MHE) or K_c (of the MPC) that is valid by
//! construction, 1 ≤ K ≤ [`MAX_ITERATIONS`], so a validated setting cannot hold K = 0.

use crate::MAX_ITERATIONS;

/// An iteration budget K with 1 ≤ K ≤ [`MAX_ITERATIONS`]: each time step runs exactly K
/// iterations of Φ. Built only by [`Iterations::new`] (or by deserialising, which checks the
/// same range), so every value held is a budget the estimator can run.
///
/// ```
/// use qp_iter::{Iterations, IterationsError};
/// let k = Iterations::new(40)?;
/// assert_eq!((k.get(), k.to_string()), (40, "40".to_string()));
/// assert_eq!(Iterations::new(0), Err(IterationsError::Zero));
/// # Ok::<(), IterationsError>(())
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct Iterations(std::num::NonZeroUsize);

/// Why a number is not an [`Iterations`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum IterationsError {
    /// K = 0: no iteration runs, so nothing is estimated.
    #[error("is 0, but the iteration count K must be at least 1")]
    Zero,
    /// K above [`MAX_ITERATIONS`].
    #[error(
        "is {value}, above the limit {limit} (each time step runs K iterations); a certified K beyond it \
         is not practical to run"
    )]
    AboveLimit {
        /// The number given.
        value: usize,
        /// [`MAX_ITERATIONS`].
        limit: usize,
    },
}

impl Iterations {
    /// K = 1: one iteration per time step (the lifted loop's one-step map is read at it).
    pub const ONE: Self = Self(std::num::NonZeroUsize::MIN);

    /// The budget `k`, or why it is not one (0, or above [`MAX_ITERATIONS`]).
    pub fn new(k: usize) -> Result<Self, IterationsError> {
        if k > MAX_ITERATIONS {
            return Err(IterationsError::AboveLimit {
                value: k,
                limit: MAX_ITERATIONS,
            });
        }
        std::num::NonZeroUsize::new(k)
            .map(Self)
            .ok_or(IterationsError::Zero)
    }

    /// K as a number (≥ 1).
    pub const fn get(self) -> usize {
        self.0.get()
    }
}

impl std::fmt::Display for Iterations {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        self.0.fmt(f)
    }
}

impl From<Iterations> for usize {
    fn from(k: Iterations) -> Self {
        k.get()
    }
}

impl TryFrom<usize> for Iterations {
    type Error = IterationsError;
    fn try_from(k: usize) -> Result<Self, IterationsError> {
        Self::new(k)
    }
}

#[cfg(feature = "serde")]
impl serde::Serialize for Iterations {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_u64(self.get() as u64)
    }
}

#[cfg(feature = "serde")]
impl<'de> serde::Deserialize<'de> for Iterations {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let k = usize::deserialize(d)?;
        Self::new(k).map_err(serde::de::Error::custom)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_range_is_one_to_the_limit() {
        assert_eq!(Iterations::new(0), Err(IterationsError::Zero));
        assert_eq!(Iterations::new(1).map(Iterations::get), Ok(1));
        assert_eq!(
            Iterations::new(MAX_ITERATIONS).map(Iterations::get),
            Ok(MAX_ITERATIONS)
        );
        assert_eq!(
            Iterations::new(MAX_ITERATIONS + 1),
            Err(IterationsError::AboveLimit {
                value: MAX_ITERATIONS + 1,
                limit: MAX_ITERATIONS
            })
        );
    }

    #[cfg(feature = "serde")]
    #[test]
    fn deserialising_checks_the_range() {
        let k: Iterations = serde_json::from_str("7").expect("7 is a budget");
        assert_eq!(
            (k.get(), serde_json::to_string(&k).ok()),
            (7, Some("7".into()))
        );
        let e = serde_json::from_str::<Iterations>("0").expect_err("0 is not a budget");
        assert!(e.to_string().contains("at least 1"), "{e}");
    }
}
