//! BVH micro-benchmarks (criterion): build time per million triangles, closest-hit throughput for
//! coherent (camera) and incoherent (diffuse-bounce-like) rays, and memory per triangle.
//! The mesh is a procedurally displaced, subdivided sphere, so no scene file is needed.
//!
//! Run: `cargo bench --bench bvh`. Before criterion's groups it prints the build-time scaling
//! for 1M, 2M and 4M triangles (time per n·log2 n should stay flat for O(n log n)).

use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use std::time::Instant;
use trayecto::accel::Bvh;
use trayecto::geometry::primitive::{MeshAttributes, NO_LIGHT};
use trayecto::geometry::triangle::TriangleVerts;
use trayecto::geometry::{GeometryStore, Ray};
use trayecto::math::Vec3;
use trayecto::sampling::rng::Pcg32;

/// A UV sphere with `n` ≈ target triangles, radially displaced by a few sine waves.
fn bumpy_sphere(target: usize) -> GeometryStore {
    let rings = ((target as f64 / 2.0).sqrt()) as usize;
    let segments = rings.max(3);
    let p = |i: usize, j: usize| {
        let theta = std::f32::consts::PI * i as f32 / rings as f32;
        let phi = 2.0 * std::f32::consts::PI * j as f32 / segments as f32;
        let r = 1.0 + 0.05 * (7.0 * theta).sin() * (11.0 * phi).cos();
        Vec3::new(
            theta.sin() * phi.cos(),
            theta.cos(),
            theta.sin() * phi.sin(),
        ) * r
    };
    let mut g = GeometryStore::default();
    let mut attrs = MeshAttributes::default();
    for i in 0..rings {
        for j in 0..segments {
            let (a, b, c, d) = (p(i, j), p(i + 1, j), p(i + 1, j + 1), p(i, j + 1));
            for (p0, p1, p2) in [(a, b, c), (a, c, d)] {
                g.tri_mesh.push((0, attrs.indices.len() as u32));
                g.tri_light.push(NO_LIGHT);
                g.triangles.push(TriangleVerts { p0, p1, p2 });
                attrs.indices.push([0, 0, 0]);
            }
        }
    }
    g.meshes.push(attrs);
    g
}

fn coherent_rays(n: usize) -> Vec<Ray> {
    let side = (n as f64).sqrt() as usize;
    (0..side * side)
        .map(|k| {
            let (x, y) = (
                (k % side) as f32 / side as f32,
                (k / side) as f32 / side as f32,
            );
            let d = Vec3::new((x - 0.5) * 0.8, (y - 0.5) * 0.8, -1.0).normalize();
            Ray::new(Vec3::new(0.0, 0.0, 3.0), d)
        })
        .collect()
}

fn incoherent_rays(n: usize) -> Vec<Ray> {
    let mut rng = Pcg32::new(5, 1);
    (0..n)
        .map(|_| {
            // From random points inside the sphere towards random directions, like diffuse bounces.
            let o = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 1.2 - 0.6;
            let d = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0 - 1.0;
            Ray::new(o, d.normalize_or(Vec3::Z))
        })
        .collect()
}

fn memory_per_triangle(g: &GeometryStore, bvh: &Bvh) -> f64 {
    let bytes = bvh.heap_bytes()
        + g.triangles.len() * std::mem::size_of::<TriangleVerts>()
        + g.tri_mesh.len() * 8
        + g.tri_light.len() * 4;
    bytes as f64 / g.triangles.len() as f64
}

fn print_build_scaling() {
    println!("BVH build scaling (time / (n log2 n) should stay roughly constant):");
    let mut base = None;
    for millions in [1usize, 2, 4] {
        let g = bumpy_sphere(millions * 1_000_000);
        let n = g.triangles.len() as f64;
        let t = Instant::now();
        let bvh = Bvh::build(&g);
        let secs = t.elapsed().as_secs_f64();
        let per = secs / (n * n.log2());
        let ratio = base.map_or(1.0, |b: f64| per / b);
        base.get_or_insert(per);
        println!(
            "  {:>9} tris  {:>7.3} s  {:>6.1} ns/(n log n)  ratio {:>5.2}  {:>5.1} bytes/tri  depth {}",
            g.triangles.len(),
            secs,
            per * 1e9,
            ratio,
            memory_per_triangle(&g, &bvh),
            bvh.stats().max_depth
        );
    }
}

fn benches(c: &mut Criterion) {
    print_build_scaling();
    let g = bumpy_sphere(1_000_000);
    let mut group = c.benchmark_group("bvh_build");
    group.sample_size(10);
    group.throughput(Throughput::Elements(g.triangles.len() as u64));
    group.bench_function(BenchmarkId::new("binned_sah", "1M"), |b| {
        b.iter(|| Bvh::build(&g))
    });
    group.finish();

    let bvh = Bvh::build(&g);
    for (name, rays) in [
        ("coherent", coherent_rays(65536)),
        ("incoherent", incoherent_rays(65536)),
    ] {
        let mut group = c.benchmark_group("bvh_closest_hit");
        group.throughput(Throughput::Elements(rays.len() as u64));
        group.bench_function(BenchmarkId::new(name, "1M tris"), |b| {
            b.iter(|| {
                rays.iter()
                    .filter(|r| bvh.intersect(&g, r).is_some())
                    .count()
            })
        });
        group.finish();
    }
}

criterion_group!(bvh_benches, benches);
criterion_main!(bvh_benches);
