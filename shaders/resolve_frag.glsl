/* Accumulated light batches / lights so far where a surface was drawn, the World elsewhere.
 * resolve_params: x = lights so far, y = 1 to leave the background transparent (premultiplied
 * alpha 0: an XR eye keeps Blender's own image there), z = exposure in stops (surfaces and
 * World alike, as a camera's). Zero y and z are the plain resolve. */
void main()
{
  ivec2 p = ivec2(gl_FragCoord.xy);
  vec4 sum = texelFetch(accumulation, p, 0);
  float scale = exp2(resolve_params.z);
  if (sum.a > 0.0) {
    frag_color = vec4(scale * sum.rgb / max(resolve_params.x, 1.0), 1.0);
  }
  else if (resolve_params.y > 0.5) {
    frag_color = vec4(0.0);
  }
  else {
    frag_color = vec4(scale * texelFetch(background, p, 0).rgb, 1.0);
  }
}
