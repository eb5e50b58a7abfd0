/* Shade with a batch of virtual lights and write their sum (progressive accumulation adds the
 * batches; the resolve divides by the number of lights so far).
 *
 * lights: 2 texels per light, (direction.xyz, 0) then (radiance / pdf).rgb, 0), world space.
 * camera: xyz = camera position, w = 1 (perspective); or xyz = direction towards the camera,
 *         w = 0 (orthographic).
 * v_block: this fragment's mesh's row of material_blocks, its material's mapping, texel
 *          filter and exposure (shaders/btf_mapping_lib.glsl).
 * light_range: x = first light, y = how many, z = the directions per pixel of a baked analytic
 *              object's unshadowed light (lobe_lib.glsl; the exposure multiplier is the
 *              block's M_EXPOSURE, as the OpenCL kernels read it), w = how many Blender
 *              lights scene_lights holds (shaders/scene_lights_lib.glsl). Each batch adds them
 *              × its light count, so the resolve's division by the lights so far leaves them
 *              added exactly once at every stage of the accumulation.
 * v_bake_tri, v_bake_bary: this fragment's triangle in the light bake and its barycentrics
 *              (shaders/bake_lib.glsl); v_bake_tri < 0 where the mesh has no bake to play back.
 *              A baked fragment adds the bake's light × the batch's light count, as Blender's
 *              lights: whatever the number of lights, it is converged from the first batch.
 *              An analytic one's unshadowed light takes the batch's first light as its frame
 *              (lobe_lib.glsl): later batches continue its directions' sequence.
 * world: the World's rotation and pyramid (lobe_lib.glsl). */

/* What the bake's value is per unit of (as render_baked in render_direct.cl): a measured
 * material's response at this fragment's texel to one light from the bake's light direction
 * `light_dir` (t, b, n's), times exposure (bake_response in btf_bake.h); an analytic
 * material's unshadowed light, converged per pixel with this batch's directions
 * (lobe_lib.glsl; bake_over_unshadowed). map_point ran first. */
vec3 bake_response(vec3 p, vec3 t, vec3 b, vec3 n, vec3 wo_world, vec3 light_dir)
{
  int codec = itab(H_CODEC);
  if (codec == CODEC_MLVQ || codec == CODEC_DENSE || codec == CODEC_SVD) {
    vec3 wi_world = light_dir.x * t + light_dir.y * b + light_dir.z * n;
    return btf_mapped(n, wi_world, wo_world) * mblock(M_EXPOSURE);
  }
  return lobe_light(p, t, b, n, wo_world, uint(light_range.x + 0.5), int(light_range.z + 0.5),
                    int(light_range.w));
}

void main()
{
  vec3 n = normalize(v_normal);
  vec3 wo_world = camera.w > 0.5 ? normalize(camera.xyz - v_world) : normalize(camera.xyz);
  float side = dot(n, wo_world) < 0.0 ? -1.0 : 1.0; /* back faces are shaded as seen */
  n *= side;
  vec3 t = v_tangent.xyz - n * dot(n, v_tangent.xyz);
  float t_len = length(t);
  t = t_len > 1e-8 ? t / t_len : normalize(cross(abs(n.z) < 0.9 ? vec3(0, 0, 1) : vec3(1, 0, 0), n));
  vec3 b = cross(n, t) * (v_tangent.w < 0.0 ? -1.0 : 1.0) * side;
  vec3 wo = to_tangent(wo_world, t, b, n);
  map_point(v_world, n, t, b, v_uv);
  vec3 sum = vec3(0.0);
  int first = int(light_range.x), count = int(light_range.y);
  if (v_bake_tri >= 0.0) {
    if (count > 0 && wo.z > 0.0) {
      vec3 light_dir;
      vec3 light = bake_lookup(int(v_bake_tri + 0.5), v_bake_bary, wo, light_dir);
      sum = float(count) * bake_response(v_world, t, b, n, wo_world, light_dir) * light;
    }
    frag_color = vec4(sum, 1.0);
    return;
  }
  for (int i = first; i < first + count; i++) {
    vec3 dir = texelFetch(lights, ivec2(2 * i, 0), 0).xyz;
    vec3 weight = texelFetch(lights, ivec2(2 * i + 1, 0), 0).rgb;
    vec3 wi = to_tangent(dir, t, b, n);
    if (wi.z <= 0.0 || wo.z <= 0.0) {
      continue;
    }
    sum += btf_mapped(n, dir, wo_world) * weight;
  }
  int blender_lights = int(light_range.w);
  if (count > 0 && blender_lights > 0 && wo.z > 0.0) {
    sum += float(count) * scene_lights_sum(blender_lights, v_world, t, b, n, wo_world);
  }
  frag_color = vec4(sum * mblock(M_EXPOSURE), 1.0);
}
