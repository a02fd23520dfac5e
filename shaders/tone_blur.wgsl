// Post pass 2: the horizontal half of the separable Gaussian blur of the tone image (thesis
// Fig. 6.9d), each pixel with the blur radius of its layer's style; the compose pass blurs
// the result vertically.

@fragment
fn fs_tone_blur(@builtin(position) frag: vec4<f32>) -> @location(0) vec4<f32> {
    let p = vec2<i32>(frag.xy);
    use_style(textureLoad(id_tex, p, 0).x);
    let radius = select(i32(post.tone_blur), BLUR_RADIUS, BLUR_RADIUS >= 0);
    return vec4<f32>(gaussian_tone(contour_tex, 1u, p, vec2<i32>(1, 0), radius), 0.0, 0.0, 1.0);
}
