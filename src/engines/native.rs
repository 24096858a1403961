//! The in-process Rust DEM as an [`Engine`].

use super::Engine;
use super::RunOutput;
use crate::case::Case;
use crate::case::Perturbation;
use crate::physics::dem;
use crate::rundata::provenance::{Provenance, now_utc, sha256_hex};
use std::path::Path;

#[derive(Debug, Clone, Copy, Default)]
pub struct Native {
    /// Deliberately wrong physics for negative controls; default is the case as written.
    pub perturbation: Perturbation,
    pub progress: bool,
}

impl Engine for Native {
    fn name(&self) -> &'static str {
        "native"
    }

    fn run(&self, case: &Case, _dir: &Path) -> anyhow::Result<RunOutput> {
        let start = std::time::Instant::now();
        let bar = crate::report::progress::bar(self.progress, case.n_steps, "native");
        let mut frames = Vec::new();
        dem::run(
            case,
            self.perturbation,
            |s| {
                if s.is_multiple_of(1000) {
                    bar.set_position(s);
                }
            },
            |f| {
                frames.push(f);
                Ok(())
            },
        )?;
        bar.finish_and_clear();
        let case_text = std::fs::read(&case.source).unwrap_or_default();
        let p = self.perturbation;
        let mut notes = Vec::new();
        if p.friction_factor != 1.0 || p.restitution_shift != 0.0 || p.poisson_shift != 0.0 {
            notes.push(format!("PERTURBED physics (negative control): {p:?}"));
        }
        Ok(RunOutput {
            frames,
            provenance: Provenance {
                engine: "native".into(),
                version: format!("granval {} native DEM", env!("CARGO_PKG_VERSION")),
                command: "in-process".into(),
                input_hash: sha256_hex(&case_text),
                date: now_utc(),
                wall_time_s: start.elapsed().as_secs_f64(),
                threads: rayon::current_num_threads(),
                case_file: case.source.display().to_string(),
                notes,
            },
        })
    }
}
