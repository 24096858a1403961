//! The agreement of several codes on the same beds of one penetration case: the
//! three-code table of docs/lammps-laws.md ("The three-code table: registered
//! protocol"), from the sealed summaries of runs made separately (`granval compare` for
//! native and LIGGGHTS, `compare --engine lammps` or `analyze` of a LAMMPS deck directory
//! for LAMMPS).
//!
//! Every summary must be a run's own (its run seal verifies against the case) and all of
//! them must have penetrated the same beds (their sha256 in bed order). Each engine's
//! per-bed K_phi is taken once. For each pair of codes (a, b), in the order native,
//! LIGGGHTS, LAMMPS, the per-bed ln(K_a / K_b) is judged as the case's own K_phi gate
//! judges native against its reference (docs/statistics.md: an equivalence on the 90 % t
//! interval within ln(1 + `compare.k_phi_rel`), one comparison), and against the chaos
//! spread of one engine against itself as the release suite's "Engine agreement against
//! chaos" section does ([`crate::compare::chaos::family_agreement`]). The pair native /
//! reference of a `compare` run therefore gives that run's own K_phi gate, value for
//! value.

use crate::case::penetration::PenetrationCase;
use crate::compare::chaos::{FamilyAgreement, family_agreement};
use crate::compare::sweep::CaseSummary;
use crate::compare::{Check, Comparison, Gate, Rule};
use crate::experiments::chaos::{ChaosRecord, PENETRATION};
use crate::experiments::runner::CaseOutcome;
use crate::numerics::stats::Estimate;
use anyhow::{Context, Result, bail, ensure};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// The order of the registered table: native - LIGGGHTS, native - LAMMPS,
/// LIGGGHTS - LAMMPS; an engine of another name comes after them.
const ORDER: [&str; 3] = ["native", "liggghts", "lammps"];

/// Each engine's per-bed K_phi over the runs, the beds' sha256 and where each engine's
/// values came from.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Gathered {
    pub engines: BTreeMap<String, Vec<f64>>,
    pub bed_hashes: Vec<String>,
    pub sources: Vec<String>,
}

/// The verified summaries of `case` in `runs` (each a run's case directory, or an output
/// directory holding `<case name>/`), merged: every engine once, the same beds in all.
/// An error names the directory: no summary of the case, a seal that does not verify,
/// other beds, an engine whose per-bed values differ between two runs.
pub(crate) fn gather(case: &PenetrationCase, runs: &[PathBuf]) -> Result<Gathered> {
    ensure!(!runs.is_empty(), "--runs: no run directory given");
    let mut engines: BTreeMap<String, Vec<f64>> = BTreeMap::new();
    let mut from: BTreeMap<String, PathBuf> = BTreeMap::new();
    let mut beds: Option<(Vec<String>, PathBuf)> = None;
    let mut sources = Vec::new();
    for run in runs {
        let dir = crate::experiments::suite::find_summary(std::slice::from_ref(run), &case.name)
            .with_context(|| {
                format!(
                    "--runs {}: no summary of case {} there (neither {}/summary.json naming it nor {}/{}/summary.json)",
                    run.display(),
                    case.name,
                    run.display(),
                    run.display(),
                    case.name
                )
            })?;
        let v = super::run_seal::verify(&dir, case)
            .with_context(|| format!("--runs {}", run.display()))?;
        sources.push(v.describe());
        let s: CaseSummary = v.summary;
        ensure!(
            !s.bed_hashes.is_empty(),
            "--runs {}: the summary names no beds (written before beds were recorded); codes can only be paired bed by bed on known beds",
            dir.display()
        );
        match &beds {
            None => beds = Some((s.bed_hashes.clone(), dir.clone())),
            Some((h, first)) if *h != s.bed_hashes => bail!(
                "--runs {}: other beds than {} ({} vs {} beds, or another sha256): the codes must have penetrated the same beds",
                dir.display(),
                first.display(),
                s.bed_hashes.len(),
                h.len()
            ),
            Some(_) => {}
        }
        for (name, e) in s.engines {
            ensure!(
                e.k_phi_beds.len() == s.bed_hashes.len(),
                "{}: {name} has {} per-bed K_phi for {} beds",
                dir.display(),
                e.k_phi_beds.len(),
                s.bed_hashes.len()
            );
            if let Some(old) = engines.get(&name) {
                ensure!(
                    *old == e.k_phi_beds,
                    "--runs {}: {name}'s per-bed K_phi differ from those in {}: two different runs of one engine; give each engine once",
                    dir.display(),
                    from[&name].display()
                );
                continue;
            }
            from.insert(name.clone(), dir.clone());
            engines.insert(name, e.k_phi_beds);
        }
    }
    ensure!(
        engines.len() >= 2,
        "--runs: only {} among the summaries; agreement needs two engines or more",
        engines.keys().cloned().collect::<Vec<_>>().join(", ")
    );
    Ok(Gathered {
        engines,
        bed_hashes: beds.map(|b| b.0).unwrap_or_default(),
        sources,
    })
}

/// The engines in the table's order.
fn ordered(engines: &BTreeMap<String, Vec<f64>>) -> Vec<&str> {
    let mut names: Vec<&str> = engines.keys().map(String::as_str).collect();
    names.sort_by_key(|n| (ORDER.iter().position(|o| o == n).unwrap_or(ORDER.len()), *n));
    names
}

/// One pair of codes: the 90 % interval of the mean per-bed ln(K_a / K_b), the
/// equivalence check and the agreement against chaos (mean, sd, F).
#[derive(Debug, Clone)]
pub(crate) struct Pair {
    pub a: String,
    pub b: String,
    /// The 90 % decision interval of the mean ln ratio (NaN with fewer than two beds).
    pub interval90: (f64, f64),
    pub check: Check,
    pub chaos: FamilyAgreement,
}

/// Every pair of `engines` judged with the margin ln(1 + `k_phi_rel`) and against the
/// chaos values `chaos` (c_k = ln(K_k / K'_k) of one engine against itself).
pub(crate) fn pairs(
    case: &str,
    engines: &BTreeMap<String, Vec<f64>>,
    k_phi_rel: f64,
    chaos: &[f64],
) -> Vec<Pair> {
    let names = ordered(engines);
    let mut out = Vec::new();
    for (i, a) in names.iter().enumerate() {
        for b in &names[i + 1..] {
            let logs: Vec<f64> = engines[*a]
                .iter()
                .zip(&engines[*b])
                .map(|(x, y)| (x / y).ln())
                .collect();
            let estimate = Estimate::mean(&logs);
            let interval90 = estimate
                .map(|e| e.decision_interval())
                .unwrap_or((f64::NAN, f64::NAN));
            let check = Check::decided(
                format!("{case}: K_phi {a} / {b}"),
                Gate::KPhi,
                format!("ln(K_{a} / K_{b}), mean over beds"),
                &[Comparison {
                    what: format!("bed by bed ln(K_{a} / K_{b})"),
                    estimate,
                    rule: Rule::Equivalence {
                        margin: (1.0 + k_phi_rel).ln(),
                    },
                    m: 1,
                }],
                format!(
                    "per bed: {}; the same rule as the case's K_phi gate (docs/lammps-laws.md, \"The three-code table\")",
                    logs.iter()
                        .map(|v| format!("{v:+.4}"))
                        .collect::<Vec<_>>()
                        .join(", ")
                ),
            );
            let chaos = family_agreement(&format!("{a} / {b}"), &logs, chaos);
            out.push(Pair {
                a: a.to_string(),
                b: b.to_string(),
                interval90,
                check,
                chaos,
            });
        }
    }
    out
}

/// `granval agreement CASE --runs DIR... --chaos FILE`: the checks (one K_phi
/// equivalence per pair of codes) and the report sections (per-bed K_phi of every
/// engine; every pair against chaos).
pub fn agreement(case_file: &Path, runs: &[PathBuf], chaos_file: &Path) -> Result<CaseOutcome> {
    let case = PenetrationCase::load(case_file).with_context(|| {
        format!(
            "{}: `granval agreement` takes a penetration case",
            case_file.display()
        )
    })?;
    let chaos = ChaosRecord::read(chaos_file)?;
    ensure!(
        chaos.kind == PENETRATION && !chaos.values().is_empty(),
        "--chaos {}: kind {:?} with {} values; the agreement of penetration codes is judged against a penetration chaos record (`granval chaos` of a penetration case)",
        chaos_file.display(),
        chaos.kind,
        chaos.values().len()
    );
    let g = gather(&case, runs)?;
    let pairs = pairs(
        &case.name,
        &g.engines,
        case.tolerances.k_phi_rel,
        chaos.values(),
    );
    let names = ordered(&g.engines);
    let mut beds = format!(
        "Each engine's K_phi per bed (each bed's own FDR over regime C, as the engine gate of docs/statistics.md).\n\n| bed | sha256 | {} |\n|---|---|{}\n",
        names.join(" | "),
        "---|".repeat(names.len())
    );
    for (k, h) in g.bed_hashes.iter().enumerate() {
        beds.push_str(&format!(
            "| {k} | {} | {} |\n",
            &h[..h.len().min(12)],
            names
                .iter()
                .map(|n| format!("{:.3}", g.engines[*n][k]))
                .collect::<Vec<_>>()
                .join(" | ")
        ));
    }
    let (s_c, df) = chaos.spread();
    let mut table = format!(
        "Every pair of codes on the same beds against the chaos spread of one engine against itself: s_c = {s_c:.4} over {df} beds of {} ({}, family {:?}; `granval chaos`). The 95 % interval is of the mean; F = sd^2 / s_c^2 with its upper-tail p.\n\n| pair | beds | mean ln ratio | 90 % interval | equivalence | 95 % interval | sd per bed | F (p) | z vs chaos | verdict |\n|---|---|---|---|---|---|---|---|---|---|\n",
        chaos.case,
        chaos_file.display(),
        chaos.family
    );
    for p in &pairs {
        let r = &p.chaos;
        let i90 = p.interval90;
        table.push_str(&format!(
            "| {} / {} | {} | {:+.4} | [{:+.4}, {:+.4}] | {} | [{:+.4}, {:+.4}] | {:.4} | {:.2} ({:.3}) | {:+.2} | {} |\n",
            p.a,
            p.b,
            r.n_pairs,
            r.mean_log,
            i90.0,
            i90.1,
            p.check.status.label(),
            r.interval95.0,
            r.interval95.1,
            r.sd_engines,
            r.f_ratio,
            r.f_p,
            r.z_chaos,
            r.verdict
        ));
    }
    let section = |title: &str, body: String| crate::report::Section {
        title: title.into(),
        body,
        figures: Vec::new(),
    };
    let mut notes = g.sources;
    notes.push(chaos_provenance(&case.name, &g.bed_hashes, &chaos));
    notes.push(format!(
        "margin ln(1 + {}) = {:.4} (the case's compare.k_phi_rel); chaos record {}",
        case.tolerances.k_phi_rel,
        (1.0 + case.tolerances.k_phi_rel).ln(),
        chaos_file.display()
    ));
    Ok(CaseOutcome {
        checks: pairs.into_iter().map(|p| p.check).collect(),
        run: None,
        notes,
        sections: vec![
            section("K_phi per bed", beds),
            section("Codes against chaos", table),
        ],
    }
    .for_case(&case.name))
}

/// Whose chaos the pairs are judged against: this case on these beds, or a record
/// borrowed from another case or other beds (allowed, since a family shares one chaos
/// spread, but a reader must see that s_c was not measured on the table's beds).
fn chaos_provenance(case: &str, bed_hashes: &[String], chaos: &ChaosRecord) -> String {
    let same_case = chaos.case == case;
    let same_beds = chaos.bed_hashes == bed_hashes;
    match (same_case, same_beds) {
        (true, true) => format!(
            "chaos record of this case on these {} beds (family {:?})",
            bed_hashes.len(),
            chaos.family
        ),
        (true, false) => format!(
            "chaos record of this case on other beds ({} beds, family {:?}): s_c is of the same \
             physics, not of the table's beds",
            chaos.bed_hashes.len(),
            chaos.family
        ),
        (false, _) => format!(
            "chaos record of another case ({:?}, {} beds, family {:?}), not of {case:?}: s_c \
             is borrowed from that case; judge F against it only if the two cases share their \
             physics",
            chaos.case,
            chaos.bed_hashes.len(),
            chaos.family
        ),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::compare::Status;

    /// The LIGGGHTS and LAMMPS legs of the three-code table (docs/data/three-code/,
    /// per-bed K_phi as `analyze` reduced them): the pair's mean, 90 % interval and
    /// verdict as SciPy's t quantiles give them (docs/data/three-code/
    /// pairs-liggghts-lammps.json), and F and its p against the CI-scale chaos record.
    #[test]
    fn the_liggghts_lammps_pair_of_the_three_code_table() {
        let engines: BTreeMap<String, Vec<f64>> = [
            (
                "liggghts".to_string(),
                vec![
                    21.058377891035995,
                    25.340399380502575,
                    22.18513062973211,
                    28.576373199944605,
                    25.883503119042157,
                    34.02730911241504,
                    26.53098454987978,
                    26.616624026217,
                ],
            ),
            (
                "lammps".to_string(),
                vec![
                    25.116139230639675,
                    28.670538363573637,
                    27.68195955099656,
                    25.802478760431264,
                    25.64216506520289,
                    29.606914491718346,
                    24.76515344266135,
                    24.04533455899002,
                ],
            ),
        ]
        .into();
        let chaos = ChaosRecord::read(
            &Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/data/chaos/ci-seeds-20261200.json"),
        )
        .unwrap();
        let p = pairs("t", &engines, 0.1, chaos.values());
        assert_eq!(p.len(), 1);
        let p = &p[0];
        assert_eq!((p.a.as_str(), p.b.as_str()), ("liggghts", "lammps"));
        let (lo, hi) = p.interval90;
        approx::assert_relative_eq!(
            p.chaos.mean_log,
            -0.012492160336163348,
            max_relative = 1e-12
        );
        approx::assert_relative_eq!(lo, -0.10687897990597994, max_relative = 1e-9);
        approx::assert_relative_eq!(hi, 0.08189465923365324, max_relative = 1e-9);
        assert_eq!(p.check.status, Status::Inconclusive, "{:?}", p.check);
        approx::assert_relative_eq!(p.chaos.chaos_sd, 0.05854854697540171, max_relative = 1e-12);
        approx::assert_relative_eq!(p.chaos.f_ratio, 5.79, max_relative = 1e-3);
    }

    /// The rule can fail and pass: the same beds 30 % apart fail the margin ln 1.1; a pair
    /// within 1 % on every bed passes; the order is native, LIGGGHTS, LAMMPS.
    #[test]
    fn pairs_fail_pass_and_keep_the_registered_order() {
        let base = [21.0, 25.3, 22.2, 28.6, 25.9, 34.0, 26.5, 26.6];
        let engines: BTreeMap<String, Vec<f64>> = [
            ("lammps".to_string(), base.iter().map(|k| k * 1.3).collect()),
            ("liggghts".to_string(), base.to_vec()),
            (
                "native".to_string(),
                base.iter()
                    .enumerate()
                    .map(|(i, k)| k * (1.0 + 0.005 * if i % 2 == 0 { 1.0 } else { -1.0 }))
                    .collect(),
            ),
        ]
        .into();
        let p = pairs("t", &engines, 0.1, &[0.05, -0.06, 0.04]);
        let names: Vec<(&str, &str)> = p.iter().map(|p| (p.a.as_str(), p.b.as_str())).collect();
        assert_eq!(
            names,
            [
                ("native", "liggghts"),
                ("native", "lammps"),
                ("liggghts", "lammps")
            ]
        );
        assert_eq!(p[0].check.status, Status::Pass, "{:?}", p[0].check);
        assert_eq!(p[1].check.status, Status::Fail, "{:?}", p[1].check);
        assert_eq!(p[2].check.status, Status::Fail, "{:?}", p[2].check);
        assert!(
            p[2].chaos.verdict.contains("systematic"),
            "{:?}",
            p[2].chaos
        );
    }

    /// The report says whose chaos it judges against: the table's own case and beds,
    /// its case on other beds, or another case.
    #[test]
    fn the_chaos_record_is_named_as_own_or_borrowed() {
        let chaos = ChaosRecord::read(
            &Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/data/chaos/three-code-ci.json"),
        )
        .unwrap();
        let own = chaos_provenance(&chaos.case, &chaos.bed_hashes, &chaos);
        assert!(
            own.starts_with("chaos record of this case on these 8 beds"),
            "{own}"
        );
        let other_beds = chaos_provenance(&chaos.case, &chaos.bed_hashes[..3], &chaos);
        assert!(other_beds.contains("on other beds"), "{other_beds}");
        let other = chaos_provenance("another-case", &chaos.bed_hashes, &chaos);
        assert!(
            other.contains("of another case") && other.contains("borrowed"),
            "{other}"
        );
    }
}
