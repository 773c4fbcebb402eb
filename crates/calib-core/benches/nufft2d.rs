//! The type-1 2-D NUFFT of `calib_core::nufft2d` on `calib tdr`'s use case: time-ordered
//! samples of a spin-down, `K = 2` weight sets, `j_max = 127` (Chebyshev orders of the normalized
//! time, `a_n = acos(τ_n)`) and `m_max = 1016` (harmonics of the encoder's reading `b_n`, a
//! decelerating phase over 400 turns). Also the 1-D path (`j_max = 0`) at the same `m_max`.
//!
//! The samples (10⁶, 32 MB) are generated once, outside the timed loop. The full-size case
//! (10⁷ samples) runs by hand: `cargo test --release -p calib-core --test it nufft2d:: -- --ignored`.
//!
//! ```text
//! cargo bench -p calib-core --bench nufft2d
//! ```

use std::hint::black_box;
use std::time::Duration;

use calib_core::nufft2d::type1;
use criterion::{Criterion, Throughput, criterion_group, criterion_main};

#[path = "../tests/it/support/spin_down.rs"]
mod support;
use support::spin_down;

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
