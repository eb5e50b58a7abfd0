/* Accumulated light batches / lights so far where a surface was drawn, the World elsewhere. */
void main()
{
  ivec2 p = ivec2(gl_FragCoord.xy);
  vec4 sum = texelFetch(accumulation, p, 0);
  vec4 world = texelFetch(background, p, 0);
  frag_color = sum.a > 0.0 ? vec4(sum.rgb / max(resolve_params.x, 1.0), 1.0) : vec4(world.rgb, 1.0);
}
