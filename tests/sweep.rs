//! Machine-configuration sweeps (issue 6).

use std::path::Path;

use crate::util::{json, num, ok, repo, tempdir, text, vcnc};

const KEYS: [&str; 2] = ["--set", "axes.X.controller.vff=0.3:0.7:10"];
const KEYS2: [&str; 2] = [
    "--set",
    "axes.Y.controller.design.wn_hz=60,65,70,73.5,75,80,85,90,95,100",
];

fn sweep(out: &Path, extra: &[&str]) {
    let mut args = vec![
        "sweep",
        "machines/nmv5000.toml",
        "gcode/spiral.ngc",
        "--quiet",
    ];
    args.extend_from_slice(&KEYS);
    args.extend_from_slice(&KEYS2);
    args.extend_from_slice(&["--out", out.to_str().unwrap()]);
    args.extend_from_slice(extra);
    ok(&vcnc(&args));
}

fn rows(path: &Path) -> Vec<Vec<String>> {
    std::fs::read_to_string(path)
        .unwrap()
        .lines()
        .map(|l| l.split(',').map(str::to_string).collect())
        .collect()
}

#[test]
fn hundred_configurations_equal_predict_and_shards_merge_back() {
    let dir = tempdir();
    let models = dir.path().join("models");
    ok(&vcnc(&[
        "identify",
        "machines/nmv5000.toml",
        "--quiet",
        "--out",
        models.to_str().unwrap(),
    ]));
    let model = models.join("model.toml");
    let full = dir.path().join("full");
    sweep(&full, &["--model", model.to_str().unwrap()]);
    let table = rows(&full.join("sweep.csv"));
    assert_eq!(table.len(), 101, "header + 100 configurations");
    let h = &table[0];
    let col = |name: &str| {
        h.iter()
            .position(|c| c == name)
            .unwrap_or_else(|| panic!("no column {name}"))
    };
    assert!(table[1..].iter().all(|r| r[col("status")] == "ok"));
    let summary = json(&full.join("summary.json"));
    assert_eq!(summary["configurations"].as_u64(), Some(100));
    assert!(summary["best"]["index"].is_u64());

    // A few configurations against `vcnc predict` on the equivalent machine file.
    let base: toml::Table =
        toml::from_str(&std::fs::read_to_string(repo("machines/nmv5000.toml")).unwrap()).unwrap();
    std::fs::copy(
        repo("machines/nmv5000.urdf"),
        dir.path().join("nmv5000.urdf"),
    )
    .unwrap();
    for &i in &[0usize, 37, 99] {
        let row = &table[1 + i];
        assert_eq!(row[0], i.to_string());
        let vff: f64 = row[1].parse().unwrap();
        let wn: f64 = row[2].parse().unwrap();
        let mut t = base.clone();
        t["axes"]["X"]["controller"]["vff"] = toml::Value::Float(vff);
        t["axes"]["Y"]["controller"]["design"]["wn_hz"] = toml::Value::Float(wn);
        let file = dir.path().join(format!("m{i}.toml"));
        std::fs::write(&file, toml::to_string(&t).unwrap()).unwrap();
        let out = dir.path().join(format!("p{i}"));
        ok(&vcnc(&[
            "predict",
            file.to_str().unwrap(),
            "gcode/spiral.ngc",
            "--model",
            model.to_str().unwrap(),
            "--quiet",
            "--out",
            out.to_str().unwrap(),
        ]));
        let p = json(&out.join("summary.json"));
        for (column, key) in [
            ("contour_max_um", "contour_um.true_max"),
            ("contour_rms_um", "contour_um.true_rms"),
            ("orientation_max_mrad", "orientation_mrad.true_max"),
            ("predicted_contour_max_um", "contour_um.predicted_max"),
            ("discrepancy_max_um", "contour_um.discrepancy_max"),
        ] {
            let a: f64 = row[col(column)].parse().unwrap();
            assert_eq!(a, num(&p, key), "configuration {i}: {column}");
        }
    }

    // Three shards, merged, equal the unsharded sweep row for row.
    let mut shard_dirs = Vec::new();
    for s in 1..=3 {
        let d = dir.path().join(format!("shard{s}"));
        sweep(
            &d,
            &[
                "--model",
                model.to_str().unwrap(),
                "--shard",
                &format!("{s}/3"),
            ],
        );
        shard_dirs.push(d);
    }
    let merged = dir.path().join("merged");
    let mut args = vec!["sweep-merge"];
    let names: Vec<String> = shard_dirs
        .iter()
        .map(|d| d.to_str().unwrap().to_string())
        .collect();
    args.extend(names.iter().map(String::as_str));
    args.extend_from_slice(&["--out", merged.to_str().unwrap()]);
    ok(&vcnc(&args));
    assert_eq!(
        std::fs::read_to_string(merged.join("sweep.csv")).unwrap(),
        std::fs::read_to_string(full.join("sweep.csv")).unwrap()
    );
    // The merged summary names the same best configuration, with its key values.
    let (m, f) = (
        json(&merged.join("summary.json")),
        json(&full.join("summary.json")),
    );
    assert_eq!(
        m["best"], f["best"],
        "merged {} vs full {}",
        m["best"], f["best"]
    );
    assert!(m["best"]["values"]["axes.X.controller.vff"].is_f64());
    // The merge draws the same plots as the sweep (issue 11: it drew none): two keys make one
    // heat map (issue 16: not one scatter per key).
    let (a, b) = (merged.join("sweep_map.svg"), full.join("sweep_map.svg"));
    assert!(a.exists(), "{} missing", a.display());
    assert_eq!(std::fs::read(&a).unwrap(), std::fs::read(&b).unwrap());
}

#[test]
fn thread_count_does_not_change_results() {
    let dir = tempdir();
    let (a, b) = (dir.path().join("a"), dir.path().join("b"));
    for (out, threads) in [(&a, "1"), (&b, "2")] {
        let o = vcnc(&[
            "--threads",
            threads,
            "sweep",
            "machines/nmv5000.toml",
            "gcode/spiral.ngc",
            "--quiet",
            // ζ = 0.5 is unreachable on X: failed rows must not depend on the thread count either.
            "--keep-going",
            "--set",
            "axes.C.plant.coulomb_torque=0.2,0.8,1.6",
            "--set",
            "axes.X.controller.design.zeta=0.3,0.5",
            "--out",
            out.to_str().unwrap(),
        ]);
        assert!(o.status.success(), "{:?}", text(&o));
    }
    assert_eq!(
        std::fs::read(a.join("sweep.csv")).unwrap(),
        std::fs::read(b.join("sweep.csv")).unwrap()
    );
}

#[test]
fn bad_configurations_are_refused_before_running_or_reported_per_row() {
    // Configurations whose machine cannot be built (an unknown key, an impossible design) are
    // found before anything runs: the sweep is refused with exit code 2, naming how many, the
    // first one and its error, and writes nothing (issue 30).
    let dir = tempdir();
    let refused = dir.path().join("refused");
    let r = vcnc(&[
        "sweep",
        "machines/nmv5000.toml",
        "gcode/spiral.ngc",
        "--quiet",
        "--set",
        "axes.X.controller.design.zeta=0.39,-0.5",
        "--out",
        refused.to_str().unwrap(),
    ]);
    assert_eq!(r.status.code(), Some(2), "{:?}", text(&r));
    let msg = text(&r).1;
    assert!(
        msg.contains("1 of 2 configurations of the sweep cannot be built")
            && msg.contains("#1 axes.X.controller.design.zeta=-0.5")
            && msg.contains("--keep-going"),
        "{msg}"
    );
    assert!(
        !refused.exists(),
        "a refused sweep wrote {}",
        refused.display()
    );
    // With --keep-going they fail their own configurations, not the sweep; a sweep whose every
    // configuration failed measured nothing: it keeps its rows and exits 1 (issue 11).
    let out = dir.path().join("s");
    let all_failed = vcnc(&[
        "sweep",
        "machines/nmv5000.toml",
        "gcode/spiral.ngc",
        "--quiet",
        "--keep-going",
        "--set",
        "axes.X.controller.design.zeta=0.39,-0.5",
        "--set",
        "axes.X.plant.no_such_key=1",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(all_failed.status.code(), Some(1), "{:?}", text(&all_failed));
    assert!(
        text(&all_failed)
            .1
            .contains("all 2 configurations of the sweep failed"),
        "{:?}",
        text(&all_failed)
    );
    let t = rows(&out.join("sweep.csv"));
    assert_eq!(t.len(), 3);
    for r in &t[1..] {
        let s = r[status_col(&t)..].join(",");
        assert!(
            s.starts_with("\"error:") && s.contains("no_such_key"),
            "{s}"
        );
    }
    let out2 = dir.path().join("s2");
    ok(&vcnc(&[
        "sweep",
        "machines/nmv5000.toml",
        "gcode/spiral.ngc",
        "--quiet",
        "--keep-going",
        "--set",
        "axes.X.controller.design.zeta=0.39,-0.5",
        "--out",
        out2.to_str().unwrap(),
    ]));
    let t = rows(&out2.join("sweep.csv"));
    assert_eq!(t[1][status_col(&t)], "ok");
    assert!(
        t[2][status_col(&t)..].join(",").contains("zeta"),
        "{:?}",
        t[2]
    );
}

fn status_col(t: &[Vec<String>]) -> usize {
    t[0].iter().position(|c| c == "status").unwrap()
}
