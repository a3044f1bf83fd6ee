//! The integration tests, linked into one binary. Every test binary links the whole crate
//! with wgpu and its dependencies, so one binary instead of twenty cuts a fresh clone's build
//! time and disk use; each module here was once a file of its own and keeps its name
//! (`cargo test --release --test suite view::` runs one). A new test file belongs in this
//! folder as one more module, not beside it in `tests/`, where it would link on its own.
//!
//! `tests/formats.rs` and `tests/mutation.rs` stay binaries of their own: each installs a
//! global allocator that measures the loaders' requests, which must not watch the rest.

#[path = "../common/mod.rs"]
mod common;

mod analysis_link;
mod analyze;
mod bad_inputs;
mod choosy;
mod cli_usage;
mod docs;
mod export;
mod factor_analysis;
mod gen;
mod gpu_synth;
mod interrupt;
mod isotropic;
mod loaders;
mod mesh_cache;
mod mesh_cli;
mod modules;
mod outputs;
mod pipeline;
mod presets;
mod quality;
mod recipes;
mod render;
mod repetition;
mod soler;
mod streams;
mod surface;
mod synth;
mod tileable;
mod view;
mod viewer_window;
