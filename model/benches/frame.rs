//! Whole-frame rendering throughput of the fixed-point model (single thread).
//!
//! `cargo bench -p model --features std` prints the time per frame; criterion's
//! throughput line gives Melem/s, i.e. Mpixel/s.

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use model::{render_frame_rgb888, Light, FRAME_BYTES, HEIGHT, WIDTH};
use std::hint::black_box;

fn frame(c: &mut Criterion) {
    let mut group = c.benchmark_group("model");
    group.throughput(Throughput::Elements((WIDTH * HEIGHT) as u64));
    group.sample_size(20);
    let mut out = vec![0u8; FRAME_BYTES];
    for (name, (x, y, z)) in [("frame near light", (3.0, 4.0, -2.0)), ("frame far light", (1500.0, 2000.0, -1000.0))] {
        let light = Light::from_world(x, y, z).expect("bench light in range");
        group.bench_function(name, |b| {
            let out: &mut [u8; FRAME_BYTES] = out.as_mut_slice().try_into().expect("frame sized");
            b.iter(|| render_frame_rgb888(black_box(&light), out))
        });
    }
    group.finish();
}

criterion_group!(benches, frame);
criterion_main!(benches);
