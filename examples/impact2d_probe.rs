//! Developer probe: prepares the beds of an impact2d case and runs native + LAMMPS,
//! printing final depths and wall times (`cargo run --example impact2d_probe CASE`).
fn main() -> anyhow::Result<()> {
    for path in std::env::args().skip(1) {
        let case = granval::case::impact2d::Impact2dCase::load(std::path::Path::new(&path))?;
        let t0 = std::time::Instant::now();
        let beds = granval::impact2d::prepare_beds(&case, false)?;
        for (p, b) in &beds.beds {
            println!(
                "{} ({:.1} s)",
                granval::impact2d::bed_note(&case, *p, b),
                t0.elapsed().as_secs_f64()
            );
        }
        let opts = granval::pipeline::Options {
            progress: false,
            ..Default::default()
        };
        let out = std::path::PathBuf::from(format!("/tmp/impact2d_probe/{}", case.name));
        let r = granval::impact2d::compare_case(&case, &opts, &out);
        for c in &r.checks {
            println!(
                "{} {}: {:.4} (tol {}) {} {}",
                if c.passed { "PASS" } else { "FAIL" },
                c.name,
                c.value,
                c.tolerance,
                c.metric,
                c.detail
            );
        }
        if let Some(run) = &r.run {
            println!(
                "wall: native {:.1} s, lammps {:.1} s",
                run.wall_time_test_s, run.wall_time_reference_s
            );
        }
        for n in &r.notes {
            println!("note: {n}");
        }
    }
    Ok(())
}
