// A plain full-screen copy: the cost floor of a post-processing pass (benchmark only).

@fragment
fn fs_copy(@builtin(position) frag: vec4<f32>) -> @location(0) vec4<f32> {
    return textureLoad(source, vec2<i32>(frag.xy), 0);
}
