//! Stage 3, the GPU: the renderer's SG shading variant (SAT paper section 5): bind and compile only what
//! the scene needs.

use super::sg_tables::SgTables;
#[cfg(feature = "internals")]
use super::pipeline_to;
use super::{array_entry, terrain_pipeline, Ledger, Ledgered, Targets};
use crate::package::shading_sats::ShadingBake;
use crate::gpu::shaders::{self, SgOmit, SgSceneUniform, SgVariant};
use crate::profile::{SG_SKY_LAYERS, SG_SKY_SIDE};
use crate::shading::scene::{Effects, Scene};
use crate::shading::{Patches, SkyTable};
use crate::{Error, Result};
use crate::profile::Profile;

/// The SG shading variant of [`super::Shading::Sg`]: a scene over the clipmap's terrain, integrated over
/// `patches`, with tables already baked from it ([`ShadingBake::bake_cached`], or out of core
/// [`ShadingBake::bake_package_cached`]; they stay in CPU memory, and fill the renderer's fixed per-level
/// tables).
/// Only what the scene needs ([`Scene::needs`]) is bound and compiled: no light table without
/// visibility (used when the scene asks for it and `bake` holds horizons), no specular code without
/// specular.
#[derive(Clone, Copy, Debug)]
pub struct SgShading<'a> {
    /// The scene (lights, material, effects).
    pub scene: &'a Scene,
    /// The patch grid of the integration.
    pub patches: Patches,
    /// The baked tables.
    pub bake: &'a ShadingBake,
    /// A term left out: [`SgOmit::None`] except in `clipsat bench shading`'s per-term breakdown.
    pub omit: SgOmit,
}

/// The two programs of one SG variant.
#[derive(Debug)]
pub(super) struct SgPrograms {
    /// Block draws (`fs_sg`).
    pub(super) block: wgpu::RenderPipeline,
    /// Skirt draws (`fs_sg_skirt`: also the see-through-the-side test).
    pub(super) skirt: wgpu::RenderPipeline,
}

/// The variants a renderer can switch between: one slot per subset of (visibility, specular, fog).
const SUBSETS: usize = 8;

/// The GPU objects of the SG shading of one scene (docs/design.md "Only the effects a scene calls for"): only
/// the tables the scene needs are baked and bound, only its effects compiled. The effects can be switched
/// off and on again within that set ([`SgState::set_effects`]): the tables stay, and each subset's programs
/// are compiled the first time it is drawn and kept.
#[derive(Debug)]
pub(super) struct SgState {
    /// The variant drawn.
    pub(super) variant: SgVariant,
    /// The variant built: the scene's effects, the most any switch can turn on.
    built: SgVariant,
    pub(super) baked: Vec<&'static str>,
    pub(super) bound: Vec<&'static str>,
    pub(super) layout_entries: usize,
    pub(super) tables: SgTables,
    /// The scene as drawn (visibility as bound, fog fitted), its sky table and uniform: what a CPU twin of
    /// the frame shades with.
    pub(super) scene: Scene,
    pub(super) sky: SkyTable,
    pub(super) uniform: SgSceneUniform,
    /// The scene's sky table (`shading/sky_table.rs`), written once.
    _sky: wgpu::Texture,
    _uniform: wgpu::Buffer,
    pub(super) _layout: wgpu::BindGroupLayout,
    pub(super) group: wgpu::BindGroup,
    pipeline_layout: wgpu::PipelineLayout,
    targets: Targets,
    /// The programs of each subset of the built effects compiled so far ([`subset_index`]).
    programs: [Option<SgPrograms>; SUBSETS],
}

/// The slot of `v`'s effects in [`SgState`]'s programs.
fn subset_index(v: SgVariant) -> usize {
    usize::from(v.visibility) | usize::from(v.specular) << 1 | usize::from(v.fog) << 2
}

/// Compiles variant `v`'s module and its two programs.
fn compile(
    dev: &mut Ledgered<'_>,
    v: SgVariant,
    layout: &wgpu::PipelineLayout,
    targets: &Targets,
) -> SgPrograms {
    let module = dev.shader_module("sg_clipmap.wgsl", shaders::sg_clipmap(v));
    programs(dev, &module, layout, targets)
}

/// The block and skirt programs of an SG module (`fs_sg`, `fs_sg_skirt`).
pub(super) fn programs(
    dev: &mut Ledgered<'_>,
    module: &wgpu::ShaderModule,
    layout: &wgpu::PipelineLayout,
    targets: &Targets,
) -> SgPrograms {
    SgPrograms {
        block: terrain_pipeline(
            dev,
            "clipmap sg pipeline",
            layout,
            module,
            "fs_sg",
            targets,
        ),
        skirt: terrain_pipeline(
            dev,
            "clipmap sg skirt pipeline",
            layout,
            module,
            "fs_sg_skirt",
            targets,
        ),
    }
}

impl SgState {
    /// Bakes nothing of the terrain: creates the per-level tables (filled by each prepare from `s.bake`)
    /// and the scene's sky table (integrated here, once, unless `sky` is the scene's already: a rebuild
    /// on a new device), and makes the group-2 layout, group and pipelines.
    pub(super) fn new(
        dev: &mut Ledgered<'_>,
        queue: &wgpu::Queue,
        profile: &Profile,
        s: &SgShading<'_>,
        layouts: [&wgpu::BindGroupLayout; 2],
        targets: &Targets,
        sky: Option<&SkyTable>,
    ) -> Result<Self> {
        let bake = s.bake;
        let mut scene = s.scene.clone();
        scene.effects.visibility &= bake.azimuths() > 0;
        // The data's extent and spacing as the bake recorded them: a streamed terrain has no heightmap.
        let (ex, ey) = bake.data_extent_m();
        scene.fit_fog(ex.hypot(ey));
        let needs = scene.needs();
        let variant = SgVariant {
            patches: s.patches,
            visibility: needs.bind_visibility,
            specular: needs.specular_code,
            fog: needs.fog,
            omit: s.omit,
        };
        let sky_table = match sky {
            Some(t) => t.clone(),
            None => SkyTable::new(&scene, s.patches),
        };
        let tables = SgTables::new(dev, profile, bake, variant.visibility, &scene, &sky_table)?;
        let mut u = SgSceneUniform::new(&scene, bake.azimuths())?;
        // The sun count in z is the scene's (SgSceneUniform::new).
        u.grid[0] = bake.data_spacing();
        let uniform = dev.buffer_init(
            "sg scene",
            bytemuck::bytes_of(&u),
            wgpu::BufferUsages::UNIFORM,
        );
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
        if let (true, Some(view)) = (variant.visibility, tables.light_view.as_ref()) {
            entries.push(array_entry(2, wgpu::ShaderStages::FRAGMENT));
            resources.push(wgpu::BindGroupEntry {
                binding: 2,
                resource: wgpu::BindingResource::TextureView(view),
            });
            bound.push("level_light");
        }
        let layout = dev.bind_group_layout("sg shading layout", &entries);
        let group = dev.bind_group("sg shading group", &layout, &resources);
        let pipeline_layout = dev.pipeline_layout(
            "clipmap sg pipeline layout",
            &[Some(layouts[0]), Some(layouts[1]), Some(&layout)],
        );
        let mut programs: [Option<SgPrograms>; SUBSETS] = Default::default();
        programs[subset_index(variant)] = Some(compile(dev, variant, &pipeline_layout, targets));
        Ok(SgState {
            scene: scene.clone(),
            sky: sky_table.clone(),
            uniform: u,
            variant,
            built: variant,
            baked: bake.baked().to_vec(),
            bound,
            layout_entries: entries.len(),
            tables,
            _sky: sky,
            _uniform: uniform,
            _layout: layout,
            group,
            pipeline_layout,
            targets: *targets,
            programs,
        })
    }

    /// The shading probe's programs for the variant drawn (`fs_sg_probe`, `fs_sg_probe_skirt`) into
    /// `colour` targets, compiled through `dev` (the probe's own ledger).
    #[cfg(feature = "internals")]
    pub(super) fn probe_programs(
        &self,
        dev: &mut Ledgered<'_>,
        colour: &[Option<wgpu::ColorTargetState>],
    ) -> SgPrograms {
        let module = dev.shader_module("sg_clipmap.wgsl (probe)", shaders::sg_clipmap(self.variant));
        let layout = &self.pipeline_layout;
        let t = &self.targets;
        SgPrograms {
            block: pipeline_to(dev, "sg probe", layout, &module, "fs_sg_probe", t, colour),
            skirt: pipeline_to(
                dev,
                "sg probe skirt",
                layout,
                &module,
                "fs_sg_probe_skirt",
                t,
                colour,
            ),
        }
    }

    /// The programs of the variant drawn.
    pub(super) fn programs(&self) -> &SgPrograms {
        self.programs[subset_index(self.variant)]
            .as_ref()
            .expect("the drawn variant's programs are compiled when it is set")
    }

    /// Draws with `effects` (visibility, specular and fog; synthesis is not a shading effect) from now on.
    /// Each must be one the renderer was built with: what the scene left out has no table, binding or
    /// code to switch on, and asking for it is refused. The tables, the bind group and the sky table stay
    /// as they are; a subset drawn for the first time compiles its module and programs here (recorded in
    /// `ledger`, zero bytes), and later switches to it create nothing.
    pub(super) fn set_effects(
        &mut self,
        device: &wgpu::Device,
        ledger: &mut Ledger,
        effects: Effects,
    ) -> Result<()> {
        let b = self.built;
        let asked = [
            ("visibility", effects.visibility, b.visibility),
            ("specular", effects.specular, b.specular),
            ("fog", effects.fog, b.fog),
        ];
        if let Some((name, ..)) = asked.iter().find(|(_, want, have)| *want && !*have) {
            return Err(Error::Invalid {
                what: format!("SG effect `{name}`"),
                reason: format!(
                    "the renderer was built for `{}`, without it: build it with a scene that asks for it",
                    b.label()
                ),
            });
        }
        let v = SgVariant {
            visibility: effects.visibility,
            specular: effects.specular,
            fog: effects.fog,
            ..b
        };
        let slot = &mut self.programs[subset_index(v)];
        if slot.is_none() {
            let mut dev = Ledgered::new(device);
            *slot = Some(compile(&mut dev, v, &self.pipeline_layout, &self.targets));
            ledger.extend(&dev.finish());
        }
        self.variant = v;
        Ok(())
    }
}
