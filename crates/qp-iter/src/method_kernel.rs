//! Choosing the dense kernel of a built map ([`MethodMap::set_kernel`]).

use crate::kernel::Kernel;
use crate::method::MethodMap;

impl MethodMap {
    /// Runs the map's dense steps on `kernel` instead of the detected one, and returns it.
    /// With [`Kernel::portable`] the steps are the plain-Rust loops of the portable path,
    /// which `mhe-embedded` and the C that `cargo xtask export` writes repeat operation for
    /// operation (no FMA, the same summation order), so their estimates agree bit for bit.
    /// The ADMM split on general rows has no dense kernel and is returned unchanged.
    ///
    /// ```
    /// use faer::{mat, Mat};
    /// use lti_model::BoxSet;
    /// use qp_iter::{Method, ParametricQp};
    /// use qp_iter::kernel::Kernel;
    /// let qp = ParametricQp::new(mat![[2.0, 0.0], [0.0, 1.0]], vec![-2.0, -4.0],
    ///     Mat::zeros(2, 0), BoxSet::symmetric(&[2.0, 2.0]).unwrap()).unwrap();
    /// let map = Method::FISTA.build(qp).unwrap().with_kernel(Kernel::portable());
    /// # let _ = map;
    /// ```
    pub fn with_kernel(mut self, kernel: Kernel) -> Self {
        self.set_kernel(kernel);
        self
    }

    /// [`MethodMap::with_kernel`] in place.
    pub fn set_kernel(&mut self, kernel: Kernel) {
        match self {
            MethodMap::Pg(m) => m.set_kernel(kernel),
            MethodMap::Fista(m) => m.set_kernel(kernel),
            MethodMap::Admm(m) => m.set_kernel(kernel),
            MethodMap::AdmmSplit(_) => {}
            MethodMap::Scaled(m) => m.inner_mut().set_kernel(kernel),
        }
    }
}
