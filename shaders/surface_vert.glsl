/* Meshes arrive in world space (the host applies world_from_object once per upload). */
void main()
{
  v_world = pos;
  v_normal = nor;
  v_uv = uv;
  v_tangent = tan;
  v_block = blk;
  v_bake_tri = bake_tri;
  v_bake_bary = bake_bary;
  gl_Position = clip_from_world * vec4(pos, 1.0);
}
