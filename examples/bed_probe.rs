//! Developer probe: kinetic energy during bed settling of an impact2d case.
fn main() -> anyhow::Result<()> {
    let path = std::env::args().nth(1).expect("case file");
    let case = granval::case::impact2d::Impact2dCase::load(std::path::Path::new(&path))?;
    let spec = granval::dem2d::impact::bed_spec(&case, case.base.packing);
    let s = case.scales;
    let mut last = 0.0;
    let t0 = std::time::Instant::now();
    let b = granval::dem2d::bed::prepare(&spec, |t, ke| {
        if t - last > 250.0 * s.tau_c || t < last {
            last = t;
            println!(
                "t = {:7.0} tau_c  KE = {:.3e} m g d  ({:.1} s)",
                t / s.tau_c,
                ke / (s.m * s.g0 * s.d),
                t0.elapsed().as_secs_f64()
            );
        }
    })?;
    println!("{}", granval::impact2d::bed_note(&case, spec.packing, &b));
    Ok(())
}
