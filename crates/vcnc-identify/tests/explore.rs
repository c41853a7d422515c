mod support;
use support::*;
use vcnc_identify::*;
use vcnc_drive::{ClosedLoopModel, ControllerSpec, PoleDesign};

fn run(name: &str, params: &vcnc_drive::DriveParams, seed: u64, o: &IdentifyOptions) {
    let truth = params.closed_loop_model().unwrap();
    let tr = drive_trace(params, &paper_program(seed));
    let val = drive_trace(params, &paper_program(seed + 1000));
    println!("== {name}: tracking peak {:.4} rms {:.4}", tr.tracking_peak(), tr.tracking_rms());
    let t0 = std::time::Instant::now();
    let id = identify(&tr, o).unwrap();
    let el = t0.elapsed();
    compare("paper_pso", &id.paper_pso, &truth);
    compare("identified", &id.identified, &truth);
    let r = id.refinement.as_ref().unwrap();
    let fv = fit_metrics(&id.identified, &val, o).unwrap();
    let fvp = fit_metrics(&id.paper_pso, &val, o).unwrap();
    let fvt = fit_metrics(&truth, &val, o).unwrap();
    println!("   {el:?} chosen {} stages {:?} evals {}; LS stable {} {:?}", r.chosen, r.stages.iter().map(|s| (s.sign, format!("{:.3e}", s.freerun_rms))).collect::<Vec<_>>(), r.evaluations, id.unconstrained_ls.stable, id.unconstrained_ls.poles.map(|p| (p.p_hz(), p.wn_hz(), p.zeta)));
    let rv = paper_program(seed + 1000);
    for (nm, m) in [("truth", truth), ("ident", id.identified)] {
        let xs = m.simulate(rv.as_ref(), rv.ts, &Default::default()).unwrap();
        let mx = xs.iter().zip(&val.x).fold(0.0f64, |a, (p, q)| a.max((p - q).abs()));
        println!("   analytic-derivative sim of {nm}: max err {:.3e} ({:.2}% of peak)", mx, 100.0 * mx / val.tracking_peak());
    }
    println!("   validation: peak {:.4}, identified fr rms {:.3e} max {:.3e} ({:.2}% of peak), paper max {:.3e}, truth max {:.3e}", fv.tracking_peak, fv.freerun_rms, fv.freerun_max, 100.0 * fv.freerun_max / fv.tracking_peak, fvp.freerun_max, fvt.freerun_max);
}

#[test]
#[ignore]
fn explore() {
    let o = IdentifyOptions::default();
    let mut params = vcnc_drive::table1_drive();
    for q in [1e-4, 1e-3] {
        params.encoder.resolution = q;
        for seed in [7, 3] { run(&format!("table1 q {q} seed {seed}"), &params, seed, &o); }
    }
    for ax in ['X', 'Y', 'Z', 'A', 'C'] {
        let p = vcnc_drive::nmv5000_axis_design(ax).unwrap();
        run(&format!("NMV {ax}"), &p, 11, &o);
    }
    let design = PoleDesign { p_hz: 10.7296, wn_hz: 30.569, zeta: 0.44519 };
    let mut pid = vcnc_drive::table1_drive();
    pid.controller = ControllerSpec::Pid { kp: None, ki: None, kd: None, design: Some(design), jff: 0.0, bff: 0.1 };
    run("PID", &pid, 5, &o);
    let je = 0.01 / 1.5915;
    let (lam, wn, z) = (std::f64::consts::TAU * 10.7296, std::f64::consts::TAU * 30.569, 0.44519);
    for (jh, bh) in [(1.0, 1.0), (0.8, 0.0), (0.5, 0.0)] {
        let mut smc = vcnc_drive::table1_drive();
        smc.controller = ControllerSpec::Smc { lambda: Some(lam), ks: Some(2.0 * z * wn * je), rho: Some(wn * wn * je), je_hat: Some(jh * je), be_hat: Some(bh * 0.0418572 / 1.5915), design: None };
        run(&format!("SMC jhat {jh} bhat {bh}"), &smc, 5, &o);
    }
    return;
    // bad start for NMV A and C
    for ax in ['A', 'C'] {
        let p = vcnc_drive::nmv5000_axis_design(ax).unwrap();
        let truth = p.closed_loop_model().unwrap();
        let tr = drive_trace(&p, &paper_program(11));
        let tp = truth.poles().unwrap();
        let regs = Regressors::build(&tr, &o).unwrap();
        let bad = vcnc_drive::Poles { p: tp.p * 5.0, wn: tp.wn, zeta: 2.0 };
        let start = ClosedLoopModel::from_poles(&bad, 0.0, 0.0, 0.0, 0.0);
        let r = refine(&tr, &regs, &start, &bad, &o.bounds, &o.refine).unwrap();
        compare(&format!("bad start {ax}"), &r.model, &truth);
        let bad = vcnc_drive::Poles { p: tp.p / 5.0, wn: tp.wn * 1.3, zeta: 2.0 };
        let r = refine(&tr, &regs, &start, &bad, &o.bounds, &o.refine).unwrap();
        compare(&format!("bad start2 {ax}"), &r.model, &truth);
    }
}
