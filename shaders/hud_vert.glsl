/* The HUD quad: view_corners' columns are its view-space corners (bottom-left, bottom-right,
 * top-left, top-right, w = 1); corner_uv (0 or 1 in each axis) picks one by a bilinear mix,
 * which is exact at 0 and 1. The uv interpolates perspective-correctly across the quad. */
void main()
{
  vec4 bottom = mix(view_corners[0], view_corners[1], corner_uv.x);
  vec4 top = mix(view_corners[2], view_corners[3], corner_uv.x);
  v_uv = corner_uv;
  gl_Position = clip_from_view * mix(bottom, top, corner_uv.y);
}
