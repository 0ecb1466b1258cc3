// The item buffer (PLP, Klosowski & Silva): every triangle drawn in its own
// integer, id + 1, into an R32Uint target, to read back which triangles
// the image shows.
//
// This file is appended to geometry.wgsl when the module is made
// (item_buffer.rs), so `frame` and `clip_of` are the triangle pipeline's
// own: the same positions through the same clip-space formula give the
// same coverage and depth as `vs_triangle`.

struct ItemIn {
    // Camera-relative position, world axes (GpuVertex::position).
    @location(0) position: vec3<f32>,
    // The triangle's id + 1 (0 is "no triangle").
    @location(1) item: u32,
};

struct ItemOut {
    @builtin(position) position: vec4<f32>,
    @location(0) @interpolate(flat) item: u32,
};

@vertex
fn vs_item(v: ItemIn) -> ItemOut {
    var out: ItemOut;
    out.position = clip_of(v.position);
    out.item = v.item;
    return out;
}

@fragment
fn fs_item(i: ItemOut) -> @location(0) u32 {
    return i.item;
}
