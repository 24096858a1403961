//! Coarse-graining throughput (issue 4): 1e6 contacts onto a 50^3 grid, all fields
//! (solid fraction, velocity, eq 9 and kernel stress). Run: `cargo bench --bench
//! coarse_grain`; `granval cg-bench` prints the same measurement once.

use criterion::{Criterion, criterion_group, criterion_main};
use granval::analysis::cg_bench::{grid_over, synthetic_snapshot};
use granval::analysis::coarse_grain::{CgParams, CoarseGrainer};
use std::hint::black_box;

fn bench(c: &mut Criterion) {
    let d = 2e-3;
    let snap = synthetic_snapshot(1_000_000, d);
    let pts = grid_over(&snap, 50).points();
    let params = CgParams::from_grain_diameter(d).expect("valid diameter");
    let mut g = c.benchmark_group("coarse_grain");
    g.sample_size(10);
    g.bench_function("1e6 contacts onto 50^3 (setup + fields)", |b| {
        b.iter(|| {
            let cg = CoarseGrainer::new(&snap, &snap.contacts, params).expect("snapshot");
            black_box(cg.eval(&pts))
        })
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
