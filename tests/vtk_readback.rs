//! The stress-field VTK files read back through VTK itself (Python's `vtk` package, the
//! library inside ParaView): every array loads, with every value. Needs a Python with
//! `vtkmodules` (Debian: `apt-get install python3-vtk9`, found at /usr/bin/python3, or
//! the interpreter `GRANVAL_PYTHON` names); without one it prints a SKIP line and
//! checks nothing (the Rust reader in `src/report/vtk.rs` still checks every array).

mod common;

use granval::analysis::coarse_grain::Grid3;
use granval::report::vtk::{FILL, GridData, VALID_SUFFIX, write_structured_points};
use std::path::Path;
use std::process::Command;

/// Prints, as one JSON object, every point-data array VTK's legacy reader loads (set to
/// read all of them, as ParaView's is) with its values.
const READ: &str = r#"
import json, sys
from vtkmodules.vtkIOLegacy import vtkStructuredPointsReader
from vtkmodules.util.numpy_support import vtk_to_numpy
r = vtkStructuredPointsReader()
r.SetFileName(sys.argv[1])
r.ReadAllScalarsOn(); r.ReadAllVectorsOn(); r.ReadAllTensorsOn()
r.Update()
d = r.GetOutput()
pd = d.GetPointData()
out = {"points": d.GetNumberOfPoints(), "arrays": {}}
for i in range(pd.GetNumberOfArrays()):
    a = pd.GetArray(i)
    out["arrays"][a.GetName()] = {"components": a.GetNumberOfComponents(),
        "values": [float(x) for x in vtk_to_numpy(a).reshape(-1)]}
print(json.dumps(out))
"#;

fn read(py: &str, path: &Path) -> serde_json::Value {
    let o = Command::new(py)
        .args(["-c", READ])
        .arg(path)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    serde_json::from_slice(&o.stdout).unwrap()
}

/// A field file with empty cells (NaN in every kind of array) loads completely in VTK:
/// six fields and six masks, each with a value per point, the defined values as
/// written, the empty ones the fill value with mask 0. The negative control: the same
/// kind of file with an ASCII `nan`, as granval wrote before, loads only the arrays
/// before it.
#[test]
fn stress_field_vtk_loads_completely_in_vtk() {
    let Some(py) = common::vtk_python() else {
        eprintln!("[stress_field_vtk_loads_completely_in_vtk] SKIPPED: no Python with vtk");
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let g = Grid3 {
        lo: [0.0; 3],
        spacing: 0.5,
        n: [2, 1, 2],
    };
    let nan = f64::NAN;
    let sf = [0.55, 0.6, 0.0, 0.3];
    let gb = [0.3, nan, nan, 1.0 / 3.0];
    let gk = [0.5, 0.25, nan, 0.125];
    let v = [
        [1e-3, -2.0, 0.0],
        [nan; 3],
        [0.5, nan, 1.0],
        [1.0, 2.0, 3.0],
    ];
    let t = [
        [1.0, 2.0, 3.0, 4.0, 5.0, 6.0],
        [nan; 6],
        [1e5, 2e5, 3e5, -1.5, 0.0, 7.0],
        [0.1, 0.2, 0.3, 0.4, 0.5, 0.6],
    ];
    let t2 = [[7.0; 6], [nan; 6], [8.0; 6], [9.5e-12; 6]];
    let p = dir.path().join("fields_00.vtk");
    let scalars: [(&str, &[f64]); 3] = [
        ("solid_fraction", &sf),
        ("gamma_basic", &gb),
        ("gamma_kernel", &gk),
    ];
    let data = GridData {
        scalars: scalars.to_vec(),
        vectors: vec![("velocity", &v)],
        tensors: vec![("stress_basic", &t), ("stress_kernel", &t2)],
    };
    write_structured_points(&p, "granval CG fields", &g, &data).unwrap();
    let got = read(&py, &p);
    assert_eq!(got["points"], 4);
    let arrays = got["arrays"].as_object().unwrap();
    assert_eq!(arrays.len(), 12, "{:?}", arrays.keys().collect::<Vec<_>>());
    let full = |s: &[f64; 6]| vec![s[0], s[3], s[4], s[3], s[1], s[5], s[4], s[5], s[2]];
    let mut want: Vec<(&str, usize, Vec<Vec<f64>>)> = scalars
        .iter()
        .map(|(n, s)| (*n, 1, s.iter().map(|x| vec![*x]).collect()))
        .collect();
    want.push(("velocity", 3, v.iter().map(|x| x.to_vec()).collect()));
    want.push(("stress_basic", 9, t.iter().map(full).collect()));
    want.push(("stress_kernel", 9, t2.iter().map(full).collect()));
    for (name, comps, points) in want {
        let a = &arrays[name];
        assert_eq!(a["components"], comps, "{name}");
        let vals: Vec<f64> = a["values"]
            .as_array()
            .unwrap()
            .iter()
            .map(|x| x.as_f64().unwrap())
            .collect();
        assert_eq!(vals.len(), 4 * comps, "{name}");
        let mask: Vec<f64> = arrays[&format!("{name}{VALID_SUFFIX}")]["values"]
            .as_array()
            .unwrap()
            .iter()
            .map(|x| x.as_f64().unwrap())
            .collect();
        for (k, pt) in points.iter().enumerate() {
            let ok = pt.iter().all(|x| x.is_finite());
            assert_eq!(mask[k], if ok { 1.0 } else { 0.0 }, "{name} mask at {k}");
            for (j, x) in pt.iter().enumerate() {
                let expect = if x.is_finite() { *x } else { FILL };
                assert_eq!(vals[k * comps + j], expect, "{name}[{k}][{j}]");
            }
        }
    }

    let old = dir.path().join("old.vtk");
    std::fs::write(
        &old,
        "# vtk DataFile Version 3.0\nt\nASCII\nDATASET STRUCTURED_POINTS\nDIMENSIONS 2 1 1\nORIGIN 0 0 0\nSPACING 1 1 1\nPOINT_DATA 2\nSCALARS phi double 1\nLOOKUP_TABLE default\n1e0\nnan\nSCALARS psi double 1\nLOOKUP_TABLE default\n3e0\n4e0\n",
    )
    .unwrap();
    let o = Command::new(&py)
        .args(["-c", READ])
        .arg(&old)
        .output()
        .unwrap();
    let back: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert!(
        back["arrays"].as_object().unwrap().len() < 2,
        "an ASCII nan no longer stops VTK's reader: {back}"
    );
}
