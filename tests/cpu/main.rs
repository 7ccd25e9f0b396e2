//! The CPU test binary: every stage that needs no GPU adapter (source, bake, plan, shading maths, shader
//! translation). One binary instead of one per file, so `cargo test` links wgpu once for all of them (the
//! layout of wgpu's own test suite). Run one module with `cargo test --test cpu clipmap::`.

mod bake_step;
mod clipmap;
mod drawn;
mod flight;
mod fly_paths;
mod fragment;
mod fuzz_parsers;
mod imagery;
mod imagery_rings;
mod layering;
mod lod;
mod package;
mod plan_time;
mod profiles;
mod query;
mod sat;
mod scene;
mod sg_numerics;
mod shaders_glsl;
mod shaders_glslang;
mod shading;
mod sources;
