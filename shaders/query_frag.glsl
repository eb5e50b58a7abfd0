/* Evaluate the BTF for the query stored at this fragment's texel of query_a/query_b:
 * query_a = (u, v, theta_i, phi_i), query_b = (theta_v, phi_v, valid, 0). */
void main()
{
  ivec2 p = ivec2(gl_FragCoord.xy);
  vec4 a = texelFetch(query_a, p, 0);
  vec4 b = texelFetch(query_b, p, 0);
  vec3 value = vec3(0.0);
  if (b.z > 0.5) {
    value = btf_evaluate(a.xy, a.z, a.w, b.x, b.y);
  }
  frag_color = vec4(value, 1.0);
}
