//! The rough conductor through the float32 engine alone (no Python): million evaluations/s at 1 and 2 threads,
//! median and best of 31 runs, for profiling the lane kernels. Run: cargo run --release --example engine_scaling
use _lamina::engine::Rows;
use _lamina::models::{self, Args};
use _lamina::stack::{Layer, Stack};
use std::time::Instant;
fn main() {
    let n = 1_000_000;
    let (mut wi, mut wo) = (vec![0f32; 3 * n], vec![0f32; 3 * n]);
    let mut s = 1u64;
    let mut r = || {
        s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (s >> 40) as f32 / (1u64 << 24) as f32
    };
    for i in 0..n {
        for w in [&mut wi, &mut wo] {
            let z = 0.05 + 0.95 * r();
            let p = std::f32::consts::TAU * r();
            let q = (1.0 - z * z).sqrt();
            w[3 * i..3 * i + 3].copy_from_slice(&[q * p.cos(), q * p.sin(), z]);
        }
    }
    let stack = Stack::new(
        vec![Layer::Conductor { ior: vec![0.2, 0.45, 1.4], k: vec![3.6, 2.5, 1.9], alpha: (0.3, 0.3), angle: 0.0 }],
        1.0,
    )
    .unwrap();
    let info = models::info("microfacet").unwrap();
    let args = Args::parse(info, &[("g2".into(), models::Value::Text("separable".into()))]).unwrap();
    let p = models::prepare("microfacet", &stack, &args).unwrap();
    let mut out = vec![0f32; 3 * n];
    for threads in [1, 2] {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        pool.install(|| {
            let mut times: Vec<f64> = (0..31)
                .map(|_| {
                    let t = Instant::now();
                    assert!(p.eval_f32(Rows::Packed(&wi), Rows::Packed(&wo), None, &mut out));
                    t.elapsed().as_secs_f64()
                })
                .collect();
            times.sort_by(f64::total_cmp);
            let rate = |t: f64| n as f64 / t / 1e6;
            println!("{threads} threads: median {:.1} M/s (best {:.1})", rate(times[15]), rate(times[0]));
        });
    }
}
