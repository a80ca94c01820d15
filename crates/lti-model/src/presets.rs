//! Built-in plants used by examples, tests and benchmarks.

use faer::mat;

use crate::system::LtiSystem;

/// The case-study **stand-in** plant of design.md §4 (the paper does not print its A, B):
/// A, B of a common 4-state, 2-input benchmark and the paper's C = [0.1, 0.3, 0.8, 0.5],
/// with w¹ entering every state and w² the output. `scenarios/case-study.toml` holds the same
/// plant (a test keeps the two equal).
///
/// ```
/// let sys = lti_model::presets::case_study_plant();
/// assert_eq!((sys.nx(), sys.nu(), sys.ny(), sys.nw()), (4, 2, 1, 5));
/// ```
pub fn case_study_plant() -> LtiSystem {
    let sys = LtiSystem::new(
        mat![
            [0.7, -0.1, 0.0, 0.0],
            [0.2, -0.5, 0.1, 0.0],
            [0.0, 0.1, 0.1, 0.0],
            [0.5, 0.0, 0.5, 0.5]
        ],
        mat![[0.0, 0.1], [0.1, 1.0], [0.1, 0.0], [0.0, 0.0]],
        mat![[0.1, 0.3, 0.8, 0.5]],
    );
    // Constant, finite, consistently shaped data: construction cannot fail.
    match sys {
        Ok(s) => s,
        Err(e) => unreachable!("the built-in case-study plant is valid: {e}"),
    }
}
