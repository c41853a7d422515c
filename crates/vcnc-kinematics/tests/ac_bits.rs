//! Bit-identity of the table-tilting A/C path with vcnc before the kinematic families
//! (commit 13c6b18): forward kinematics, the TCP track inverse, the pose inverse and the
//! spiral's sequence inverse, through the old `TableTiltingAc` methods and through
//! `Kinematics`. The hashes (FNV-1a over the outputs' bits) were recorded by running the same
//! inputs through the code of that commit.

use crate::common;

use common::{ok, spiral};
use vcnc_kinematics::nalgebra::Vector3;
use vcnc_kinematics::{
    Axes, AxisLimits, Branch, IkOptions, Kinematics, Pose, TableTiltingAc, Track,
};

/// A fixed pseudo-random stream (PCG-style LCG): the inputs are the ones hashed in 13c6b18.
struct Lcg(u64);

impl Lcg {
    fn next(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((self.0 >> 11) as f64) / ((1u64 << 53) as f64)
    }

    fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.next()
    }
}

struct Fnv(u64);

impl Fnv {
    fn new() -> Self {
        Fnv(0xcbf29ce484222325)
    }

    fn add(&mut self, v: f64) {
        for b in v.to_bits().to_le_bytes() {
            self.0 ^= u64::from(b);
            self.0 = self.0.wrapping_mul(0x100000001b3);
        }
    }
}

/// The hashes of 13c6b18, per model: forward, TCP track, inverse +1, inverse −1.
const RECORDED: [[u64; 4]; 2] = [
    [
        0xfed4a8c9c080c175,
        0x029009b236764e94,
        0x07e82ff5ae6ed33b,
        0x9f5ea687e2321520,
    ],
    [
        0x4e9419db86921ba5,
        0x309de9966114c760,
        0x78df461892daf033,
        0x2cd64573611c360e,
    ],
];

/// Runs the recorded inputs through `TableTiltingAc` (`via_enum` false) or `Kinematics`.
fn hashes(m: &TableTiltingAc, mi: u64, via_enum: bool) -> [u64; 4] {
    let kin = m.kinematics();
    let mut rng = Lcg(42 + mi);
    let mut out = [0u64; 4];
    let mut h = Fnv::new();
    for _ in 0..3000 {
        let ax = Axes::new(
            rng.range(-400.0, 400.0),
            rng.range(-300.0, 300.0),
            rng.range(-300.0, 300.0),
            rng.range(-2.5, 2.5),
            rng.range(-20.0, 20.0),
        );
        let p = if via_enum {
            kin.forward(&ax)
        } else {
            m.forward(&ax)
        };
        for v in p.p.iter().chain(p.o.iter()) {
            h.add(*v);
        }
    }
    out[0] = h.0;
    let n = 3000;
    let mut cols: Vec<Vec<f64>> = (0..15).map(|_| Vec::with_capacity(n)).collect();
    let mut tcp = Vec::with_capacity(n);
    for k in 0..n {
        for (i, c) in cols.iter_mut().enumerate() {
            let scale = if i >= 9 { 200.0 } else { 300.0 };
            c.push(rng.range(-scale, scale));
        }
        tcp.push(k % 7 != 3);
    }
    let tr = |i: usize| Track {
        pos: &cols[3 * i],
        vel: &cols[3 * i + 1],
        acc: &cols[3 * i + 2],
    };
    let res = if via_enum {
        ok(kin.inverse_tcp_track([tr(0), tr(1), tr(2)], &[tr(3), tr(4)], &tcp))
    } else {
        m.inverse_tcp_track([tr(0), tr(1), tr(2)], tr(3), tr(4), &tcp)
    };
    let mut h = Fnv::new();
    for t in &res {
        for v in t.pos.iter().chain(&t.vel).chain(&t.acc) {
            h.add(*v);
        }
    }
    out[1] = h.0;
    for (bi, b) in [Branch::Plus, Branch::Minus].into_iter().enumerate() {
        let mut h = Fnv::new();
        let mut c_prev = 0.3;
        for _ in 0..3000 {
            let tilt: f64 = rng.range(0.05, 3.0);
            let az: f64 = rng.range(-3.1, 3.1);
            let o = Vector3::new(tilt.sin() * az.cos(), tilt.sin() * az.sin(), tilt.cos())
                * rng.range(0.5, 2.0);
            let pose = Pose::new(
                Vector3::new(
                    rng.range(-300.0, 300.0),
                    rng.range(-300.0, 300.0),
                    rng.range(-300.0, 300.0),
                ),
                o,
            );
            let ax = if via_enum {
                ok(kin.inverse(&pose, b, &Axes::new(0.0, 0.0, 0.0, 0.0, c_prev)))
            } else {
                ok(m.inverse_near(&pose, b, c_prev))
            };
            c_prev = ax.c + rng.range(-1.0, 1.0);
            for v in [ax.x, ax.y, ax.z, ax.a, ax.c] {
                h.add(v);
            }
        }
        out[2 + bi] = h.0;
    }
    out
}

#[test]
fn table_tilting_ac_is_bit_identical_to_before_the_families() {
    let models = [
        ok(TableTiltingAc::new(
            Vector3::new(3.0, -4.0, 1.0),
            Vector3::new(0.0, 12.0, -100.0),
            AxisLimits::default(),
        )),
        TableTiltingAc::default(),
    ];
    for (mi, m) in models.iter().enumerate() {
        for via_enum in [false, true] {
            let got = hashes(m, mi as u64, via_enum);
            assert_eq!(
                got, RECORDED[mi],
                "model {mi}, via Kinematics: {via_enum}: {got:x?}"
            );
        }
    }
}

#[test]
fn spiral_sequence_is_bit_identical_to_before_the_families() {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../machines/nmv5000.urdf");
    let m = ok(TableTiltingAc::from_urdf_file(path));
    let n = 20_000;
    let poses = spiral(n);
    let via_urdf = ok(Kinematics::from_urdf_file(path));
    for kin in [m.kinematics(), via_urdf] {
        let sol = ok(kin.inverse_sequence(&poses, &IkOptions::default()));
        assert_eq!(sol.branch, Branch::Minus);
        let mut h = Fnv::new();
        for ax in &sol.axes {
            for v in [ax.x, ax.y, ax.z, ax.a, ax.c] {
                h.add(v);
            }
        }
        assert_eq!(h.0, 0x67f4ea6d269915d3, "{:x}", h.0);
    }
}
