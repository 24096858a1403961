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

pub fn run(
    lmp: &Lammps,
    scene: &Scene,
    n_steps: u64,
    output_every: u64,
    energy_every: u64,
    model: &EnergyModel,
    dir: &Path,
) -> Result<LammpsImpact> {
    let out = Outputs {
        n_steps,
        intruder_every: output_every,
        snapshot_every: energy_every,
    };
    let finished = lmp.run(&scene.sys, &out, dir)?;
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
    Ok(LammpsImpact {
        samples,
        energy,
        finished,
    })
}
