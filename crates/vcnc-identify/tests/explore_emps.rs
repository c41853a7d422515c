mod support;
use support::*;
use vcnc_identify::*;
use vcnc_drive::ClosedLoopModel;

fn load() -> Trace {
    let text = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/../../tests/data/emps/DATA_EMPS.csv")).unwrap();
    let (mut t, mut xr, mut x) = (vec![], vec![], vec![]);
    for line in text.lines().filter(|l| !l.starts_with('#')).skip(1) {
        let c: Vec<f64> = line.split(',').map(|v| v.trim().parse().unwrap()).collect();
        t.push(c[0]); xr.push(c[1] * 1e3); x.push(c[2] * 1e3);
    }
    Trace::from_columns(&t, &xr, &x).unwrap()
}

#[test]
#[ignore]
fn explore_emps() {
    let tr = load();
    println!("N {} ts {} tracking rms {:.4} mm; starts at rest {}", tr.len(), tr.ts, tr.tracking_rms(), tr.starts_at_rest(1.5));
    let phys = ClosedLoopModel { a1: 92.11, a2: 14412.2, a3: 0.0, b0: 0.0, b1: 0.0, b2: 14412.2, dc: 214.4 };
    let o = IdentifyOptions { bounds: PoleBounds { p_hz: [0.0, 500.0], ..Default::default() }, ..Default::default() };
    let f = fit_metrics(&phys, &tr, &o).unwrap();
    println!("physical model: freerun rms {:.3} um max {:.3} um", f.freerun_rms * 1e3, f.freerun_max * 1e3);
    for pre in [1usize, 2, 5] {
        let mut pos = vec![tr.x[0]; pre];
        pos.extend_from_slice(&tr.xr);
        let (vel, acc) = vcnc_drive::model::central_differences(&pos, tr.ts);
        let xs = phys.simulate(vcnc_drive::Reference { pos: &pos, vel: &vel, acc: &acc }, tr.ts, &Default::default()).unwrap();
        let err: Vec<f64> = xs[pre..].iter().zip(&tr.x).map(|(a, b)| a - b).collect();
        let rms = (err.iter().map(|e| e * e).sum::<f64>() / err.len() as f64).sqrt();
        let mx = err.iter().fold(0.0f64, |m, e| m.max(e.abs()));
        println!("prepend {pre}: rms {:.3} um max {:.3} um", rms * 1e3, mx * 1e3);
    }
    let t0 = std::time::Instant::now();
    let id = identify(&tr, &o).unwrap();
    println!("time {:?} moving {}", t0.elapsed(), id.moving_start);
    for (n, m) in [("paper", id.paper_pso), ("identified", id.identified), ("ls", id.unconstrained_ls.model)] {
        let f = fit_metrics(&m, &tr, &o).unwrap();
        println!("{n:>10}: {:?} poles {:?} stable {} marg {}  freerun rms {:.3} um max {:.3} um onestep {:.3} um", m, m.poles(), m.is_stable(), m.is_marginally_stable(), f.freerun_rms * 1e3, f.freerun_max * 1e3, f.onestep_rms*1e3);
    }
    println!("refine {:?}", id.refinement.as_ref().map(|r| (r.iterations, r.evaluations, r.rms, r.initial_response)));
}
