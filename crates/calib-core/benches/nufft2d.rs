//! The type-1 2-D NUFFT of `calib_core::nufft2d` on `calib tdr`'s use case: time-ordered
//! samples of a spin-down, `K = 2` weight sets, `j_max = 127` (Chebyshev orders of the normalized
//! time, `a_n = acos(τ_n)`) and `m_max = 1016` (harmonics of the encoder's reading `b_n`, a
//! decelerating phase over 400 turns). Also the 1-D path (`j_max = 0`) at the same `m_max`.
//!
//! The samples (10⁶, 32 MB) are generated once, outside the timed loop. The full-size case
//! (10⁷ samples) runs by hand: `cargo test --release -p calib-core --test nufft2d -- --ignored`.
//!
//! ```text
//! cargo bench -p calib-core --bench nufft2d
//! ```

use std::f64::consts::TAU;
use std::hint::black_box;
use std::time::Duration;

use calib_core::nufft2d::type1;
use criterion::{Criterion, Throughput, criterion_group, criterion_main};

/// `len` samples `(acos τ_n, b_n, [1, τ_n])`: `τ_n` evenly spaced over [−1, 1], `b_n` a
/// decelerating phase over 400 turns with a ±0.5 µrad SplitMix64 jitter.
fn spin_down(len: usize) -> Vec<(f64, f64, [f64; 2])> {
    let mut state = 0x5eed_u64;
    let mut uniform = move || {
        state = state.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = state;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
    };
    (0..len)
        .map(|n| {
            let u = (n as f64 + 0.5) / len as f64;
            let tau = 2.0 * u - 1.0;
            let b = TAU * 400.0 * (1.0 - (1.0 - u) * (1.0 - u)) + 1e-6 * (uniform() - 0.5);
            (tau.acos(), b, [1.0, tau])
        })
        .collect()
}

fn nufft2d(c: &mut Criterion) {
    let len = 1_000_000;
    let pts = spin_down(len);
    let mut group = c.benchmark_group("nufft2d");
    group.sample_size(20);
    group.measurement_time(Duration::from_secs(5));
    group.throughput(Throughput::Elements(len as u64));
    group.bench_function("samples=1e6/j_max=127/m_max=1016/K=2", |b| {
        b.iter(|| type1(black_box(len), 127, 1016, |n| pts[n]))
    });
    group.bench_function("samples=1e6/j_max=0/m_max=1016/K=2", |b| {
        b.iter(|| type1(black_box(len), 0, 1016, |n| pts[n]))
    });
    group.finish();
}

criterion_group!(benches, nufft2d);
criterion_main!(benches);
