//! The `trayecto` binary: the front ends (the command line in [`cli`], the web UI in [`server`])
//! on top of the library's render pipeline (`trayecto::pipeline`).

mod cli;
mod server;

/// Large allocations (texels, BVH, meshes) on transparent huge pages: fewer TLB misses on real
/// models (see `trayecto::hugepages` and BENCHMARKS.md "Session 13: data layout").
#[global_allocator]
static ALLOC: trayecto::hugepages::HugePageAlloc = trayecto::hugepages::HugePageAlloc;

fn main() -> std::process::ExitCode {
    cli::main()
}
