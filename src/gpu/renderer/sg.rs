//! Stage 3, the GPU: the renderer's SG shading variant (SAT paper section 5): bind and compile only what
//! the scene needs.

use super::sg_tables::SgTables;
use super::{array_entry, terrain_pipeline, Ledgered, Targets};
use crate::gpu::sat_textures::ShadingBake;
use crate::gpu::shaders::{self, SgOmit, SgSceneUniform, SgVariant};
use crate::profile::{SG_SKY_LAYERS, SG_SKY_SIDE};
use crate::shading::scene::Scene;
use crate::shading::{Patches, SkyTable};
use crate::{Heightmap, Profile, Result};

/// The SG shading variant of [`super::Shading::Sg`]: a scene over the terrain `terrain` (the one the
/// clipmap was built from), integrated over `patches`, with tables already baked
/// ([`ShadingBake::bake_cached`]; they stay in CPU memory, and fill the renderer's fixed per-level tables).
/// Only what the scene needs ([`Scene::needs`]) is bound and compiled: no horizon table without
/// visibility (used when the scene asks for it and `bake` holds horizons), no specular code without
/// specular.
#[derive(Clone, Copy, Debug)]
pub struct SgShading<'a> {
    /// The terrain.
    pub terrain: &'a Heightmap,
    /// The scene (lights, material, effects).
    pub scene: &'a Scene,
    /// The patch grid of the integration.
    pub patches: Patches,
    /// The baked tables.
    pub bake: &'a ShadingBake,
    /// A term left out: [`SgOmit::None`] except in `clipsat bench shading`'s per-term breakdown.
    pub omit: SgOmit,
}

/// The GPU objects of one SG shading variant (design.md "Only the effects a scene calls for"): only the
/// tables the scene needs are baked and bound, only its effects compiled.
#[derive(Debug)]
pub(super) struct SgState {
    pub(super) variant: SgVariant,
    pub(super) baked: Vec<&'static str>,
    pub(super) bound: Vec<&'static str>,
    pub(super) layout_entries: usize,
    pub(super) tables: SgTables,
    /// The scene's sky table (`shading/sky_table.rs`), written once.
    _sky: wgpu::Texture,
    _uniform: wgpu::Buffer,
    _layout: wgpu::BindGroupLayout,
    pub(super) group: wgpu::BindGroup,
    /// Block draws (`fs_sg`).
    pub(super) pipeline: wgpu::RenderPipeline,
    /// Skirt draws (`fs_sg_skirt`: also the see-through-the-side test).
    pub(super) skirt_pipeline: wgpu::RenderPipeline,
}

impl SgState {
    /// Bakes nothing of the terrain: creates the per-level tables (filled by each prepare from `s.bake`)
    /// and the scene's sky table (integrated here, once), and makes the group-2 layout, group and
    /// pipelines.
    pub(super) fn new(
        dev: &mut Ledgered<'_>,
        queue: &wgpu::Queue,
        profile: &Profile,
        s: &SgShading<'_>,
        layouts: [&wgpu::BindGroupLayout; 2],
        targets: &Targets,
    ) -> Result<Self> {
        let (hm, bake) = (s.terrain, s.bake);
        let mut scene = s.scene.clone();
        scene.effects.visibility &= bake.azimuths() > 0;
        let (ex, ey) = hm.extent_m();
        scene.fit_fog(ex.hypot(ey));
        let needs = scene.needs();
        let variant = SgVariant {
            patches: s.patches,
            visibility: needs.bind_visibility,
            specular: needs.specular_code,
            fog: needs.fog,
            omit: s.omit,
        };
        let tables = SgTables::new(dev, profile, bake, variant.visibility)?;
        let mut u = SgSceneUniform::new(&scene, bake.azimuths())?;
        #[expect(clippy::cast_precision_loss, reason = "layer counts <= 4")]
        let layers = tables.horizon_layers() as f32;
        // The sun count in z is the scene's (SgSceneUniform::new).
        u.grid[0] = hm.spacing();
        u.grid[1] = layers;
        let uniform = dev.buffer_init(
            "sg scene",
            bytemuck::bytes_of(&u),
            wgpu::BufferUsages::UNIFORM,
        );
        let sky_table = SkyTable::new(&scene, s.patches);
        let sky = dev.texture_with_data(
            queue,
            "sg sky_table",
            &crate::gpu::texture_2d(
                SG_SKY_SIDE * SG_SKY_LAYERS,
                SG_SKY_SIDE,
                1,
                wgpu::TextureFormat::Rgba32Float,
                wgpu::TextureUsages::empty(),
            ),
            bytemuck::cast_slice(sky_table.texels()),
        );
        let sky_view = dev.view("sg sky_table view", &sky, &Default::default());
        let mut entries = vec![
            wgpu::BindGroupLayoutEntry {
                binding: 0,
                visibility: wgpu::ShaderStages::FRAGMENT,
                ty: wgpu::BindingType::Buffer {
                    ty: wgpu::BufferBindingType::Uniform,
                    has_dynamic_offset: false,
                    min_binding_size: None,
                },
                count: None,
            },
            array_entry(1, wgpu::ShaderStages::FRAGMENT),
        ];
        let mut resources = vec![
            wgpu::BindGroupEntry {
                binding: 0,
                resource: uniform.as_entire_binding(),
            },
            wgpu::BindGroupEntry {
                binding: 1,
                resource: wgpu::BindingResource::TextureView(&tables.normal_view),
            },
        ];
        let (_, sky_binding) = shaders::SKY_TABLE_CLIPMAP;
        entries.push(wgpu::BindGroupLayoutEntry {
            binding: sky_binding,
            visibility: wgpu::ShaderStages::FRAGMENT,
            ty: wgpu::BindingType::Texture {
                sample_type: wgpu::TextureSampleType::Float { filterable: false },
                view_dimension: wgpu::TextureViewDimension::D2,
                multisampled: false,
            },
            count: None,
        });
        resources.push(wgpu::BindGroupEntry {
            binding: sky_binding,
            resource: wgpu::BindingResource::TextureView(&sky_view),
        });
        let mut bound = vec!["heights", "level_normal", "sky_table"];
        if let (true, Some(view)) = (variant.visibility, tables.horizon_view.as_ref()) {
            entries.push(array_entry(2, wgpu::ShaderStages::FRAGMENT));
            resources.push(wgpu::BindGroupEntry {
                binding: 2,
                resource: wgpu::BindingResource::TextureView(view),
            });
            bound.push("level_horizon");
        }
        let layout = dev.bind_group_layout("sg shading layout", &entries);
        let group = dev.bind_group("sg shading group", &layout, &resources);
        let module = dev.shader_module("sg_clipmap.wgsl", shaders::sg_clipmap(variant));
        let pipeline_layout = dev.pipeline_layout(
            "clipmap sg pipeline layout",
            &[Some(layouts[0]), Some(layouts[1]), Some(&layout)],
        );
        let pipeline = terrain_pipeline(
            dev,
            "clipmap sg pipeline",
            &pipeline_layout,
            &module,
            "fs_sg",
            targets,
        );
        let skirt_pipeline = terrain_pipeline(
            dev,
            "clipmap sg skirt pipeline",
            &pipeline_layout,
            &module,
            "fs_sg_skirt",
            targets,
        );
        Ok(SgState {
            variant,
            baked: bake.baked().to_vec(),
            bound,
            layout_entries: entries.len(),
            tables,
            _sky: sky,
            _uniform: uniform,
            _layout: layout,
            group,
            pipeline,
            skirt_pipeline,
        })
    }
}
