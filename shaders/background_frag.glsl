/* The World behind the objects: the environment seen along each pixel's camera ray. */
void main()
{
  vec2 ndc = gl_FragCoord.xy / viewport_size * 2.0 - 1.0;
  vec4 far_point = world_from_clip * vec4(ndc, 1.0, 1.0);
  vec4 near_point = world_from_clip * vec4(ndc, -1.0, 1.0);
  vec3 d = normalize(far_point.xyz / far_point.w - near_point.xyz / near_point.w);
  frag_color = vec4(env_lookup(d), 1.0);
}
