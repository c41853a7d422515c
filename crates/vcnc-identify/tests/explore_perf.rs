mod support;
use vcnc_identify::*;

#[test]
#[ignore]
fn perf() {
    let r = support::identification_program(7, 80, 50.0, 250.0, 2500.0, 1e-3);
    let tr = support::drive_trace(&vcnc_drive::table1_drive(), &r);
    let o = IdentifyOptions::default();
    let f = Butterworth2::new(100.0, 1e-3).unwrap();
    let mut out = vec![0.0; tr.len()];
    let mut out2 = vec![0.0; tr.len()];
    let best = |f: &mut dyn FnMut()| { let mut b = std::time::Duration::MAX; for _ in 0..50 { let t = std::time::Instant::now(); f(); b = b.min(t.elapsed()); } b };
    println!("filtfilt: {:?}", best(&mut || f.filtfilt(&tr.x, &mut out)));
    println!("filtfilt2: {:?}", best(&mut || f.filtfilt_many([&tr.x, &tr.xr], [&mut out, &mut out2])));
    println!("build: {:?}", best(&mut || { let _ = Regressors::build(&tr, &o).unwrap(); }));
    let regs = Regressors::build(&tr, &o).unwrap();
    let t = std::time::Instant::now();
    for _ in 0..100 { let _ = regs.equation_error_cost().unwrap(); }
    println!("eecost: {:?}", t.elapsed() / 100);
    let cost = regs.equation_error_cost().unwrap();
    let t = std::time::Instant::now();
    let mut s = 0.0;
    for i in 0..20000 { s += cost.cost_hz(10.0 + i as f64 * 1e-4, 30.0, 0.4); }
    println!("20000 costs: {:?} {s}", t.elapsed());
    let prob = OutputErrorProblem::new(&tr, &regs);
    let t = std::time::Instant::now();
    for i in 0..20 { let _ = prob.cost_at([10.7 + i as f64 * 1e-3, 30.6, 0.44]); }
    println!("OE eval: {:?}", t.elapsed() / 20);
}
