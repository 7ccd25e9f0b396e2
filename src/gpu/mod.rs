//! Stage 3, the GPU: wgpu on the OpenGL ES 3.0 floor. Only this module (and the renderer) touches wgpu.
