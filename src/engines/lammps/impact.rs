//! An impact scene in LAMMPS: the deck of [`super::deck`], then the intruder file and
//! the snapshots streamed into the same samples the native run produces.

use super::{Finished, Lammps, Outputs, parse};
use crate::physics::dem2d::energy::{EnergyModel, SnapDisk, energies};
use crate::physics::dem2d::impact::Scene;
use crate::rundata::impact::{EnergySample, IntruderSample};
use anyhow::{Result, bail};
use std::path::Path;

pub struct LammpsImpact {
    pub samples: Vec<IntruderSample>,
    pub energy: Vec<EnergySample>,
    pub finished: Finished,
}

/// Runs the scene in LAMMPS in `dir` ([`Lammps::run`]) and reads its series ([`read`]).
pub fn run(
    lmp: &Lammps,
    scene: &Scene,
    out: &Outputs,
    model: &EnergyModel,
    dir: &Path,
) -> Result<LammpsImpact> {
    let finished = lmp.run(&scene.sys, out, dir)?;
    let (samples, energy) = read(scene, out, model, dir)?;
    Ok(LammpsImpact {
        samples,
        energy,
        finished,
    })
}

/// The intruder samples and energies of a finished run in `dir` (made by granval or by
/// hand from a deck directory), each series complete or an error.
pub fn read(
    scene: &Scene,
    out: &Outputs,
    model: &EnergyModel,
    dir: &Path,
) -> Result<(Vec<IntruderSample>, Vec<EnergySample>)> {
    let (n_steps, output_every, energy_every) =
        (out.n_steps, out.intruder_every, out.snapshot_every);
    let dt = scene.sys.dt;
    // fcm() is contacts + gravity; the observable is the contact force.
    let weight = scene.intruder_mass * scene.sys.gravity;
    let mut samples = Vec::new();
    parse::for_each_intruder_line(&dir.join(super::INTRUDER_FILE), |l| {
        samples.push(IntruderSample {
            step: l.step,
            t: l.step as f64 * dt,
            x: l.x,
            v: l.v,
            f: [l.f[0], l.f[1] + weight],
        });
        Ok(())
    })?;
    let mut energy = Vec::new();
    parse::for_each_snapshot(&dir.join(super::SNAP_FILE), |step, atoms| {
        let snap: Vec<SnapDisk> = atoms
            .iter()
            .map(|a| SnapDisk {
                type_: a.type_ - 1,
                radius: a.radius,
                mass: a.mass,
                x: a.x,
                v: a.v,
                omega: a.omega,
            })
            .collect();
        energy.push(energies(step, step as f64 * dt, &snap, model));
        Ok(())
    })?;
    let want_i = n_steps / output_every + 1;
    let want_e = n_steps / energy_every + 1;
    if samples.len() as u64 != want_i {
        bail!(
            "LAMMPS wrote {} intruder samples in {}, expected {want_i} (steps 0..={n_steps} every {output_every})",
            samples.len(),
            dir.display()
        );
    }
    if energy.len() as u64 != want_e {
        bail!(
            "LAMMPS wrote {} snapshots in {}, expected {want_e}",
            energy.len(),
            dir.display()
        );
    }
    for (k, s) in samples.iter().enumerate() {
        if s.step != k as u64 * output_every {
            bail!(
                "intruder sample {k} in {} is step {}, expected {}",
                dir.display(),
                s.step,
                k as u64 * output_every
            );
        }
    }
    for (k, e) in energy.iter().enumerate() {
        if e.step != k as u64 * energy_every {
            bail!(
                "snapshot {k} in {} is step {}, expected {}",
                dir.display(),
                e.step,
                k as u64 * energy_every
            );
        }
    }
    Ok((samples, energy))
}
