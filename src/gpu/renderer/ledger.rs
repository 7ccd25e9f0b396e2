//! Stage 3, the GPU: the renderer's ledger of every GPU object it created and the bytes each holds.

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
}

/// One object [`Renderer::new`](super::Renderer::new) created.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct LedgerEntry {
    /// Its label.
    pub label: &'static str,
    /// What it is.
    pub kind: ObjectKind,
    /// GPU memory it holds (0 for objects without storage).
    pub bytes: u64,
}

/// Every GPU object the renderer created and the bytes each holds; only [`Renderer::new`](super::Renderer::new) writes it.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Ledger {
    entries: Vec<LedgerEntry>,
}

impl Ledger {
    pub(super) fn note(&mut self, label: &'static str, kind: ObjectKind, bytes: u64) {
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
}
