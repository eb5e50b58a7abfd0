/* The light bake's lookup (shaders/bake_lib.glsl) for the query at this fragment's texel:
 * query_a = (bake triangle, bu, bv, valid), query_b = (wo.xyz in the surface's frame, what):
 * what 0 answers the value, 1 the light direction. */
void main()
{
  ivec2 p = ivec2(gl_FragCoord.xy);
  vec4 a = texelFetch(query_a, p, 0);
  vec4 b = texelFetch(query_b, p, 0);
  vec3 value = vec3(0.0), light_dir = vec3(0.0);
  if (a.w > 0.5) {
    value = bake_lookup(int(a.x + 0.5), a.yz, b.xyz, light_dir);
  }
  frag_color = vec4(b.w > 0.5 ? light_dir : value, 1.0);
}
