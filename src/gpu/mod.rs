//! Stage 4, GPU: headless wgpu device, the four passes of ALGORITHM §7, readback. The only module
//! that touches wgpu. OWNER: gpu helper.
