//! Stage 3, the GPU: the ledger of every GPU object the renderer creates and the bytes each holds, and
//! [`Ledgered`], the one way the renderer creates them: each creation is recorded as it happens, so the
//! ledger cannot miss an object (a source scan test finds no other `create_*` call in the renderer).

/// What a GPU object is, for the [`Ledger`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ObjectKind {
    /// A buffer (bytes counted).
    Buffer,
    /// A texture (bytes counted).
    Texture,
    /// A texture view.
    TextureView,
    /// A shader module.
    ShaderModule,
    /// A bind group layout.
    BindGroupLayout,
    /// A bind group.
    BindGroup,
    /// A pipeline layout.
    PipelineLayout,
    /// A render pipeline.
    RenderPipeline,
    /// A sampler (draped imagery's colour rings, filtered by the GPU).
    Sampler,
}

/// One object the renderer created.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct LedgerEntry {
    /// Its label.
    pub label: &'static str,
    /// What it is.
    pub kind: ObjectKind,
    /// GPU memory it holds (0 for objects without storage).
    pub bytes: u64,
}

/// Kinds of [`ObjectKind`].
const KINDS: usize = 9;

/// Every GPU object the renderer created and the bytes each holds; only [`Ledgered`] writes it. Two
/// ledgers are equal when they list the same objects (their creation times aside).
#[derive(Clone, Debug, Default)]
pub struct Ledger {
    entries: Vec<LedgerEntry>,
    /// Objects created with their contents, each copied in through a staging buffer of wgpu's own.
    staged: usize,
    /// Nanoseconds spent creating objects, by kind ([`ObjectKind`] as an index).
    nanos: [u64; KINDS],
}

impl PartialEq for Ledger {
    fn eq(&self, other: &Self) -> bool {
        self.entries == other.entries && self.staged == other.staged
    }
}

impl Eq for Ledger {}

impl Ledger {
    fn note(&mut self, label: &'static str, kind: ObjectKind, bytes: u64) {
        self.entries.push(LedgerEntry { label, kind, bytes });
    }

    /// The objects, in creation order.
    pub fn entries(&self) -> &[LedgerEntry] {
        &self.entries
    }

    /// Objects created.
    pub fn count(&self) -> usize {
        self.entries.len()
    }

    /// Bytes of GPU memory held.
    pub fn bytes(&self) -> u64 {
        self.entries.iter().map(|e| e.bytes).sum()
    }

    /// Objects of `kind`.
    pub fn count_of(&self, kind: ObjectKind) -> usize {
        self.entries.iter().filter(|e| e.kind == kind).count()
    }

    /// Appends `other`'s entries (e.g. a headless target's objects after the renderer's).
    pub fn extend(&mut self, other: &Ledger) {
        self.entries.extend_from_slice(&other.entries);
        self.staged += other.staged;
        for (a, b) in self.nanos.iter_mut().zip(other.nanos) {
            *a += b;
        }
    }

    /// Wall time spent creating the objects of `kind` (the device's calls; for a render pipeline on GL
    /// that is the shaders' translation, compilation and linking, for a shader module WGSL's parsing and
    /// validation).
    pub fn creation_time(&self, kind: ObjectKind) -> std::time::Duration {
        std::time::Duration::from_nanos(self.nanos[kind as usize])
    }

    /// [`Ledger::creation_time`] of every kind together.
    pub fn total_creation_time(&self) -> std::time::Duration {
        std::time::Duration::from_nanos(self.nanos.iter().fold(0u64, |a, &n| a.saturating_add(n)))
    }

    /// Objects created with their contents ([`Ledgered::buffer_init`], [`Ledgered::texture_with_data`]):
    /// wgpu copies each in through a staging buffer of its own until the queue next runs. wgpu's live
    /// buffer counter counts those on some backends (Vulkan, GL with `GL_EXT_buffer_storage`: NVIDIA, Mesa's
    /// ES 3.2) and not on others (GL without it: Mesa's ES 3.0), so a check of the counter allows for
    /// them; they are not the renderer's.
    pub fn staged(&self) -> usize {
        self.staged
    }
}

/// Bytes a texture of `desc` holds (one mip level).
pub fn texture_bytes(desc: &wgpu::TextureDescriptor<'_>) -> u64 {
    let texel = desc
        .format
        .block_copy_size(Some(wgpu::TextureAspect::All))
        .unwrap_or(4);
    // A block format's size is its blocks' (BC1, ETC2 RGB8: 8 bytes a 4 x 4 block).
    let (bw, bh) = desc.format.block_dimensions();
    u64::from(desc.size.width.div_ceil(bw))
        * u64::from(desc.size.height.div_ceil(bh))
        * u64::from(desc.size.depth_or_array_layers)
        * u64::from(texel)
        * u64::from(desc.sample_count)
}

/// A device that records every object it creates in a [`Ledger`]: the renderer's only way to create one.
/// Each method takes the object's label separately (the ledger keeps it) and sets it on the descriptor.
#[derive(Debug)]
pub struct Ledgered<'d> {
    device: &'d wgpu::Device,
    ledger: Ledger,
}

impl<'d> Ledgered<'d> {
    /// Starts an empty ledger over `device`.
    pub fn new(device: &'d wgpu::Device) -> Self {
        Self {
            device,
            ledger: Ledger::default(),
        }
    }

    /// The device, for what creates nothing (limits, error scopes).
    pub fn device(&self) -> &'d wgpu::Device {
        self.device
    }

    /// The ledger so far.
    pub fn ledger(&self) -> &Ledger {
        &self.ledger
    }

    /// The finished ledger.
    pub fn finish(self) -> Ledger {
        self.ledger
    }

    /// A texture.
    pub fn texture(
        &mut self,
        label: &'static str,
        desc: &wgpu::TextureDescriptor<'_>,
    ) -> wgpu::Texture {
        self.note(label, ObjectKind::Texture, texture_bytes(desc));
        self.note_clear_views(desc);
        let desc = wgpu::TextureDescriptor {
            label: Some(label),
            ..desc.clone()
        };
        self.timed(ObjectKind::Texture, |d| d.create_texture(&desc))
    }

    /// wgpu itself makes one view per mip level and layer of a 2D render-attachment texture, to clear it
    /// with a render pass; the ledger counts them too, so it equals what the device holds.
    fn note_clear_views(&mut self, desc: &wgpu::TextureDescriptor<'_>) {
        if desc.usage.contains(wgpu::TextureUsages::RENDER_ATTACHMENT)
            && desc.dimension == wgpu::TextureDimension::D2
        {
            for _ in 0..desc.mip_level_count * desc.size.depth_or_array_layers {
                self.note("(wgpu internal) clear view", ObjectKind::TextureView, 0);
            }
        }
    }

    /// A view of `texture`.
    pub fn view(
        &mut self,
        label: &'static str,
        texture: &wgpu::Texture,
        desc: &wgpu::TextureViewDescriptor<'_>,
    ) -> wgpu::TextureView {
        self.note(label, ObjectKind::TextureView, 0);
        let desc = wgpu::TextureViewDescriptor {
            label: Some(label),
            ..desc.clone()
        };
        self.timed(ObjectKind::TextureView, |_| texture.create_view(&desc))
    }

    /// An uninitialised buffer.
    pub fn buffer(
        &mut self,
        label: &'static str,
        size: u64,
        usage: wgpu::BufferUsages,
    ) -> wgpu::Buffer {
        self.note(label, ObjectKind::Buffer, size);
        self.timed(ObjectKind::Buffer, |d| {
            d.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size,
                usage,
                mapped_at_creation: false,
            })
        })
    }

    /// A buffer holding `contents`.
    pub fn buffer_init(
        &mut self,
        label: &'static str,
        contents: &[u8],
        usage: wgpu::BufferUsages,
    ) -> wgpu::Buffer {
        use wgpu::util::DeviceExt;
        self.note(label, ObjectKind::Buffer, contents.len() as u64);
        self.ledger.staged += 1;
        self.timed(ObjectKind::Buffer, |d| {
            d.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some(label),
                contents,
                usage,
            })
        })
    }

    /// A texture holding `data` (one mip level, layers in order).
    pub fn texture_with_data(
        &mut self,
        queue: &wgpu::Queue,
        label: &'static str,
        desc: &wgpu::TextureDescriptor<'_>,
        data: &[u8],
    ) -> wgpu::Texture {
        use wgpu::util::DeviceExt;
        self.note(label, ObjectKind::Texture, texture_bytes(desc));
        self.ledger.staged += 1;
        self.note_clear_views(desc);
        let desc = wgpu::TextureDescriptor {
            label: Some(label),
            ..desc.clone()
        };
        self.timed(ObjectKind::Texture, |d| {
            d.create_texture_with_data(
                queue,
                &desc,
                wgpu::util::TextureDataOrder::LayerMajor,
                data,
            )
        })
    }

    /// A bind group layout.
    pub fn bind_group_layout(
        &mut self,
        label: &'static str,
        entries: &[wgpu::BindGroupLayoutEntry],
    ) -> wgpu::BindGroupLayout {
        self.note(label, ObjectKind::BindGroupLayout, 0);
        self.timed(ObjectKind::BindGroupLayout, |d| {
            d.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                label: Some(label),
                entries,
            })
        })
    }

    /// A bind group.
    pub fn bind_group(
        &mut self,
        label: &'static str,
        layout: &wgpu::BindGroupLayout,
        entries: &[wgpu::BindGroupEntry<'_>],
    ) -> wgpu::BindGroup {
        self.note(label, ObjectKind::BindGroup, 0);
        self.timed(ObjectKind::BindGroup, |d| {
            d.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some(label),
                layout,
                entries,
            })
        })
    }

    /// A sampler.
    pub fn sampler(
        &mut self,
        label: &'static str,
        desc: &wgpu::SamplerDescriptor<'_>,
    ) -> wgpu::Sampler {
        self.note(label, ObjectKind::Sampler, 0);
        self.timed(ObjectKind::Sampler, |d| {
            d.create_sampler(&wgpu::SamplerDescriptor {
                label: Some(label),
                ..desc.clone()
            })
        })
    }

    /// A WGSL shader module.
    pub fn shader_module(&mut self, label: &'static str, wgsl: String) -> wgpu::ShaderModule {
        self.note(label, ObjectKind::ShaderModule, 0);
        self.timed(ObjectKind::ShaderModule, |d| {
            d.create_shader_module(wgpu::ShaderModuleDescriptor {
                label: Some(label),
                source: wgpu::ShaderSource::Wgsl(wgsl.into()),
            })
        })
    }

    /// A pipeline layout.
    pub fn pipeline_layout(
        &mut self,
        label: &'static str,
        bind_group_layouts: &[Option<&wgpu::BindGroupLayout>],
    ) -> wgpu::PipelineLayout {
        self.note(label, ObjectKind::PipelineLayout, 0);
        self.timed(ObjectKind::PipelineLayout, |d| {
            d.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                label: Some(label),
                bind_group_layouts,
                immediate_size: 0,
            })
        })
    }

    /// A render pipeline.
    pub fn render_pipeline(
        &mut self,
        label: &'static str,
        desc: &wgpu::RenderPipelineDescriptor<'_>,
    ) -> wgpu::RenderPipeline {
        self.note(label, ObjectKind::RenderPipeline, 0);
        let desc = wgpu::RenderPipelineDescriptor {
            label: Some(label),
            ..desc.clone()
        };
        self.timed(ObjectKind::RenderPipeline, |d| d.create_render_pipeline(&desc))
    }

    fn note(&mut self, label: &'static str, kind: ObjectKind, bytes: u64) {
        self.ledger.note(label, kind, bytes);
    }

    /// `create()`'s result, its wall time added to `kind`'s.
    fn timed<T>(&mut self, kind: ObjectKind, create: impl FnOnce(&wgpu::Device) -> T) -> T {
        let t = std::time::Instant::now();
        let out = create(self.device);
        let spent = u64::try_from(t.elapsed().as_nanos()).unwrap_or(u64::MAX);
        self.ledger.nanos[kind as usize] = self.ledger.nanos[kind as usize].saturating_add(spent);
        out
    }
}

#[cfg(test)]
mod tests {
    /// The renderer's files (and the headless path and SAT textures it builds on) create GPU objects only
    /// through [`super::Ledgered`]: no `create_*` call other than a frame's command encoder. A new
    /// creation elsewhere fails here instead of escaping the ledger.
    #[test]
    fn no_object_is_created_outside_the_ledger() {
        let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("src/gpu");
        let mut files: Vec<_> = std::fs::read_dir(root.join("renderer"))
            .expect("src/gpu/renderer")
            .map(|e| e.expect("dir entry").path())
            .filter(|p| p.file_name().is_some_and(|n| n != "ledger.rs"))
            .collect();
        files.push(root.join("headless.rs"));
        assert!(files.len() >= 6, "{files:?}");
        let mut found = Vec::new();
        for f in &files {
            let text = std::fs::read_to_string(f).expect("source file");
            for (i, line) in text.lines().enumerate() {
                let code = line.split("//").next().unwrap_or("");
                for (at, _) in code.match_indices(".create_") {
                    if !code[at..].starts_with(".create_command_encoder") {
                        found.push(format!("{}:{}: {}", f.display(), i + 1, line.trim()));
                    }
                }
            }
        }
        assert!(
            found.is_empty(),
            "GPU objects created outside Ledgered:\n{}",
            found.join("\n")
        );
    }
}
