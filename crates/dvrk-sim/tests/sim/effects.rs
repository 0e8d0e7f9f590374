//! Each physical effect of the vocabulary, simulated on its own, produces its signature
//! (issue 6): Coulomb friction a torque step with the velocity's sign, compliance a deflection
//! proportional to the load, backlash dead travel at reversals, latency a residual parallel to
//! the velocity, a spring an effort proportional to the displacement, a payload or a
//! counterweight error the gravity torque dvrk-kin's independent Newton-Euler gives for the
//! added mass (and, for the counterweight, its travel).
//!
//! Every test runs on both engines (`rapier::...`, `reduced::...`).

mod rapier {
    const ENGINE: dvrk_sim::Engine = dvrk_sim::Engine::Rapier;
    include!("effects/signatures.rs");
}

mod reduced {
    const ENGINE: dvrk_sim::Engine = dvrk_sim::Engine::Reduced;
    include!("effects/signatures.rs");
}
