//! The model file's `[[inertials]]` and `[inertial_covariance]` as the dynamics read them.

use crate::model::Model;

impl Model {
    /// The covariance of the parameters of `bodies` (each [`crate::dynamics::PARAMETERS_PER_BODY`]
    /// in order, positions in [`Model::bodies`]) from the model file's `[inertial_covariance]`,
    /// as its lower Cholesky factor; `None` if the file has none or it leaves out one of them.
    pub fn inertial_covariance_factor(&self, bodies: &[usize]) -> Option<nalgebra::DMatrix<f64>> {
        let c = self.spec.inertial_covariance.as_ref()?;
        let per = crate::dynamics::PARAMETERS_PER_BODY;
        let pos: Vec<usize> = bodies
            .iter()
            .map(|&b| {
                let name = &self.bodies.get(b)?.name;
                c.bodies.iter().position(|n| n == name)
            })
            .collect::<Option<_>>()?;
        let n = c.bodies.len() * per;
        let full = nalgebra::DMatrix::from_fn(n, n, |i, k| if k <= i { c.cholesky[i][k] } else { 0.0 });
        // The requested parameters' rows of L: their covariance is L_s L_s^T, refactored.
        let rows: Vec<usize> = pos.iter().flat_map(|p| p * per..(p + 1) * per).collect();
        let sel = full.select_rows(&rows);
        (&sel * sel.transpose()).cholesky().map(|ch| ch.l())
    }

    /// Body `b`'s inertial from the model file's `[[inertials]]`, if it has one.
    pub fn file_inertia(&self, b: usize) -> Option<crate::BodyInertia> {
        let name = &self.bodies.get(b)?.name;
        self.spec.inertials.iter().find(|e| &e.body == name).map(|e| crate::BodyInertia::new(e.mass, e.com, e.inertia))
    }
}

