//! Native quasi-static penetration (Feng et al. Sec. 2): the settled bed, the
//! flat-bottomed cylinder started `start_gap` above the surface and driven down the
//! axis at constant speed to `final_depth`; the force on it is recorded with its height.

use super::Simulation;
use super::intruder::FlatCylinder;
use super::packing::{Bed, container_case_with};
use crate::case::Perturbation;
use crate::case::penetration::PenetrationCase;
use crate::rundata::force::ForceSample;
use anyhow::Result;

/// Steps from the start position to the final depth.
pub fn n_steps(case: &PenetrationCase, bed: &Bed) -> u64 {
    ((start_z(case, bed) - (bed.surface_z - case.final_depth)) / case.speed / case.dt).ceil() as u64
}

/// Height of the intruder bottom at the start: `start_gap` above the highest grain top
/// under its footprint (not the mean surface), so no grain starts inside it.
pub fn start_z(case: &PenetrationCase, bed: &Bed) -> f64 {
    let highest = bed
        .spheres(case)
        .iter()
        .filter(|(x, r)| (x[0] * x[0] + x[1] * x[1]).sqrt() < case.intruder_radius + r)
        .map(|(x, r)| x[2] + r)
        .fold(bed.surface_z, f64::max);
    highest + case.start_gap
}

/// Top of the simulation box: the intruder must fit at its start position.
pub fn box_top(case: &PenetrationCase, bed: &Bed) -> f64 {
    start_z(case, bed) + case.intruder_length + case.diameter.max()
}

/// The penetration of `bed` set up and ready to step: grains in the container, the
/// intruder at its start height moving down at the case's speed, forces evaluated.
pub(crate) fn simulation(
    case: &PenetrationCase,
    bed: &Bed,
    pert: Perturbation,
) -> Result<Simulation> {
    let sim_case = container_case_with(
        case,
        bed.particles.clone(),
        bed.bodies.clone(),
        box_top(case, bed),
    );
    let mut sim = Simulation::from_case_perturbed(&sim_case, pert);
    let body = FlatCylinder::new(
        case.intruder_radius,
        case.intruder_length,
        [0.0, 0.0, start_z(case, bed)],
    );
    sim.set_intruder(body, [0.0, 0.0, -case.speed], case.intruder_type);
    // The bed was settled by the DEM: its overlaps are physical, not input errors.
    sim.setup_settled()?;
    Ok(sim)
}

pub fn run(
    case: &PenetrationCase,
    bed: &Bed,
    pert: Perturbation,
    progress: impl FnMut(u64, u64),
) -> Result<Vec<ForceSample>> {
    run_with_snapshots(case, bed, pert, &[], |_| Ok(()), progress)
}

/// [`run`], calling `on_snapshot` after the steps listed in `snapshot_steps` (0 = after
/// `setup`), with the simulation in the state whose forces were just integrated.
pub fn run_with_snapshots(
    case: &PenetrationCase,
    bed: &Bed,
    pert: Perturbation,
    snapshot_steps: &[u64],
    mut on_snapshot: impl FnMut(&Simulation) -> Result<()>,
    mut progress: impl FnMut(u64, u64),
) -> Result<Vec<ForceSample>> {
    let mut sim = simulation(case, bed, pert)?;
    let total = n_steps(case, bed);
    let sample = |sim: &Simulation| ForceSample {
        t: sim.step as f64 * case.dt,
        z_bottom: sim.intruder().expect("intruder set above").body.bottom_z(),
        f: sim.intruder_force(),
    };
    let mut out = vec![sample(&sim)];
    if snapshot_steps.contains(&0) {
        on_snapshot(&sim)?;
    }
    for _ in 0..total {
        sim.step()?;
        if snapshot_steps.contains(&sim.step) {
            on_snapshot(&sim)?;
        }
        if sim.step.is_multiple_of(case.force_every) {
            out.push(sample(&sim));
        }
        if sim.step.is_multiple_of(500) {
            progress(sim.step, total);
        }
    }
    Ok(out)
}
