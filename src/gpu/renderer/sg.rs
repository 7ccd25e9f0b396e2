//! Stage 3, the GPU: the renderer's SG shading variant (SAT paper section 5): bake, bind, compile only
//! what the scene needs.

use wgpu::util::DeviceExt;

use super::{terrain_pipeline, Renderer};
use crate::bake::horizon::DEFAULT_AZIMUTHS;
use crate::gpu::sat_textures::{SatTextures, ShadingBake, MAX_BOX_SIDE};
use crate::gpu::shaders::{self, SgSceneUniform, SgVariant};
use crate::shading::scene::Scene;
use crate::shading::Patches;
use crate::{Heightmap, Result};

/// The GPU objects of one SG shading variant (design.md "Only the effects a scene calls for"): only the
/// tables the scene needs are baked and bound, only its effects compiled.
#[derive(Debug)]
pub(super) struct SgState {
    variant: SgVariant,
    baked: Vec<&'static str>,
    bound: Vec<&'static str>,
    layout_entries: usize,
    _textures: SatTextures,
    _uniform: wgpu::Buffer,
    _layout: wgpu::BindGroupLayout,
    pub(super) group: wgpu::BindGroup,
    pub(super) pipeline: wgpu::RenderPipeline,
}

impl Renderer<'_> {
    /// Switches the renderer to SG shading (SAT paper section 5) for `scene` over the terrain `hm` (the one
    /// the clipmap was built from), integrating over `patches`; `shadows: false` drops visibility even if
    /// the scene asks for it. Bakes (through the disk cache, [`ShadingBake::bake_cached`]), binds and compiles
    /// only what the scene needs ([`Scene::needs`]): no
    /// horizon maps or visibility texture without visibility, no specular code without specular. The SG
    /// objects are outside the profile's ledger (like the SAT LOD tables of [`Renderer::set_lod`]).
    pub fn set_sg(
        &mut self,
        hm: &Heightmap,
        scene: &Scene,
        patches: Patches,
        shadows: bool,
    ) -> Result<()> {
        let mut scene = scene.clone();
        scene.effects.visibility &= shadows;
        let max_side = self.gpu.device().limits().max_texture_dimension_2d;
        let (bake, _) = ShadingBake::bake_cached(
            hm,
            &scene.needs(),
            DEFAULT_AZIMUTHS,
            max_side,
            &crate::bake::default_cache_dir(),
        )?;
        self.set_sg_baked(hm, &scene, patches, &bake)
    }

    /// [`Renderer::set_sg`] with the tables already baked (e.g. one bake shared by several patch counts).
    /// Visibility is used when the scene asks for it and `bake` holds horizons.
    pub fn set_sg_baked(
        &mut self,
        hm: &Heightmap,
        scene: &Scene,
        patches: Patches,
        bake: &ShadingBake,
    ) -> Result<()> {
        let mut scene = scene.clone();
        scene.effects.visibility &= bake.azimuths() > 0;
        let needs = scene.needs();
        let variant = SgVariant {
            patches,
            visibility: needs.bind_visibility,
            specular: needs.specular_code,
        };
        let gpu = self.gpu;
        let device = gpu.device();
        let textures = SatTextures::upload(gpu, bake)?;
        let mut u = SgSceneUniform::new(&scene, bake.azimuths())?;
        #[expect(clippy::cast_precision_loss, reason = "grid sizes <= 16385")]
        let grid = [
            (hm.width() - 1) as f32,
            (hm.height() - 1) as f32,
            bake.step() as f32,
            MAX_BOX_SIDE as f32,
        ];
        u.grid = grid;
        let sg = gpu.scoped("sg shading set-up", || {
            let uniform = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("sg scene"),
                contents: bytemuck::bytes_of(&u),
                usage: wgpu::BufferUsages::UNIFORM,
            });
            let texture = |binding, dim| wgpu::BindGroupLayoutEntry {
                binding,
                visibility: wgpu::ShaderStages::FRAGMENT,
                ty: wgpu::BindingType::Texture {
                    sample_type: wgpu::TextureSampleType::Uint,
                    view_dimension: dim,
                    multisampled: false,
                },
                count: None,
            };
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
                texture(1, wgpu::TextureViewDimension::D2),
            ];
            let mut resources = vec![
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: uniform.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: wgpu::BindingResource::TextureView(textures.normal_view()),
                },
            ];
            let mut bound = vec!["heights", "sat_normal"];
            if let (true, Some(view)) = (variant.visibility, textures.horizon_view()) {
                entries.push(texture(2, wgpu::TextureViewDimension::D2Array));
                resources.push(wgpu::BindGroupEntry {
                    binding: 2,
                    resource: wgpu::BindingResource::TextureView(view),
                });
                bound.push("sat_horizon");
            }
            let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                label: Some("sg shading"),
                entries: &entries,
            });
            let group = device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("sg shading"),
                layout: &layout,
                entries: &resources,
            });
            let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
                label: Some("sg_clipmap.wgsl"),
                source: wgpu::ShaderSource::Wgsl(shaders::sg_clipmap(variant).into()),
            });
            let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                label: Some("clipmap sg"),
                bind_group_layouts: &[
                    Some(&self._group0_layout),
                    Some(&self._group1_layout),
                    Some(&layout),
                ],
                immediate_size: 0,
            });
            let pipeline = terrain_pipeline(device, &pipeline_layout, &module, "fs_sg");
            Ok(SgState {
                variant,
                baked: bake.baked().to_vec(),
                bound,
                layout_entries: entries.len(),
                _textures: textures,
                _uniform: uniform,
                _layout: layout,
                group,
                pipeline,
            })
        })?;
        self.sg = Some(sg);
        Ok(())
    }

    /// Back to the basic shading: drops the SG textures, bind group and pipeline ([`Renderer::set_sg`]).
    pub fn set_basic_shading(&mut self) {
        self.sg = None;
    }

    /// The names of the textures the current shading binds: `heights`, plus `sat_normal` and, with
    /// visibility, `sat_horizon` under SG shading.
    pub fn bound_textures(&self) -> &[&'static str] {
        match &self.sg {
            Some(sg) => &sg.bound,
            None => &["heights"],
        }
    }

    /// The maps baked for the current shading (none for basic shading).
    pub fn baked(&self) -> &[&'static str] {
        match &self.sg {
            Some(sg) => &sg.baked,
            None => &[],
        }
    }

    /// The SG shader variant in use, if any.
    pub fn sg_variant(&self) -> Option<SgVariant> {
        self.sg.as_ref().map(|s| s.variant)
    }

    /// Entries of the SG bind group layout (group 2), if SG shading is on: 2 without visibility, 3 with.
    pub fn sg_layout_entries(&self) -> Option<usize> {
        self.sg.as_ref().map(|s| s.layout_entries)
    }
}
