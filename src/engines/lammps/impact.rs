//! An impact scene in LAMMPS: the deck of [`super::deck`], then the intruder file and
//! the snapshots streamed into the same samples the native run produces.

use super::{Finished, Lammps, Outputs, parse};
use crate::physics::dem2d::energy::{EnergyModel, SnapDisk, energies};
use crate::physics::dem2d::impact::Scene;
use crate::rundata::impact::{ContactForce, EnergySample, FieldSnapshot, GrainPos, IntruderSample};
use anyhow::{Result, bail};
use std::path::Path;

pub struct LammpsImpact {
    pub samples: Vec<IntruderSample>,
    pub energy: Vec<EnergySample>,
    pub fields: Vec<FieldSnapshot>,
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
    let (samples, energy, fields) = read(scene, out, model, dir)?;
    Ok(LammpsImpact {
        samples,
        energy,
        fields,
        finished,
    })
}

/// The bed snapshots of a finished run in `dir`: grains from `grains.dump`, contacts
/// (the touching pairs: a non-touching neighbour has zero force in single()) from
/// `contacts.dump`; every asked-for step present, nothing else.
pub(crate) fn read_fields(out: &Outputs, dir: &Path) -> Result<Vec<FieldSnapshot>> {
    let f = &out.fields;
    let mut snaps: Vec<FieldSnapshot> = Vec::new();
    if f.position_steps.is_empty() {
        return Ok(snaps);
    }
    let gpath = dir.join(super::deck::GRAINS_FILE);
    parse::for_each_table_frame(&gpath, "ATOMS", &["id", "x", "y"], |step, rows| {
        snaps.push(FieldSnapshot {
            step,
            grains: rows
                .iter()
                .map(|r| GrainPos {
                    id: r[0] as u64,
                    x: [r[1], r[2]],
                })
                .collect(),
            contacts: f.contact_steps.contains(&step).then(Vec::new),
        });
        Ok(())
    })?;
    let steps: Vec<u64> = snaps.iter().map(|s| s.step).collect();
    if steps != f.position_steps {
        bail!(
            "{}: snapshots at steps {steps:?}, expected {:?}",
            gpath.display(),
            f.position_steps
        );
    }
    if !f.contact_steps.is_empty() {
        let cpath = dir.join(super::deck::CONTACTS_FILE);
        let mut seen = Vec::new();
        parse::for_each_table_frame(
            &cpath,
            "ENTRIES",
            &["c_cpp[1]", "c_cpp[2]", "c_cpl[1]", "c_cpl[2]", "c_cpl[3]"],
            |step, rows| {
                seen.push(step);
                let Some(c) = snaps
                    .iter_mut()
                    .find(|s| s.step == step)
                    .and_then(|s| s.contacts.as_mut())
                else {
                    bail!(
                        "{}: contacts at step {step}, not asked for",
                        cpath.display()
                    );
                };
                c.extend(rows.iter().filter(|r| r[3] != 0.0 || r[4] != 0.0).map(|r| {
                    ContactForce {
                        i: r[0] as u64,
                        j: r[1] as u64,
                        f_n: r[3].abs(),
                        ft: r[4].abs(),
                    }
                }));
                Ok(())
            },
        )?;
        if seen != f.contact_steps {
            bail!(
                "{}: contacts at steps {seen:?}, expected {:?}",
                cpath.display(),
                f.contact_steps
            );
        }
    }
    Ok(snaps)
}

/// The intruder samples, energies and bed snapshots of a finished run in `dir` (made by
/// granval or by hand from a deck directory), each series complete or an error.
pub fn read(
    scene: &Scene,
    out: &Outputs,
    model: &EnergyModel,
    dir: &Path,
) -> Result<(Vec<IntruderSample>, Vec<EnergySample>, Vec<FieldSnapshot>)> {
    let (n_steps, output_every, energy_every) =
        (out.n_steps, out.intruder_every, out.snapshot_every);
    let dt = scene.sys.dt;
    // fcm() is contacts + gravity; the observable is the contact force.
    let weight = scene.intruder_mass * scene.sys.gravity;
    let mut samples = Vec::new();
    let interface = !out.tracers.is_empty();
    parse::for_each_intruder_line(&dir.join(super::INTRUDER_FILE), interface, |l| {
        samples.push(IntruderSample {
            step: l.step,
            t: l.step as f64 * dt,
            x: l.x,
            v: l.v,
            f: [l.f[0], l.f[1] + weight],
            interface_y: l.interface_y,
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
    Ok((samples, energy, read_fields(out, dir)?))
}
