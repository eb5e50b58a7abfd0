/* The HUD image is premultiplied (render/hud.py raster_text): written as it is, for the
 * ONE, ONE_MINUS_SRC_ALPHA blend (filtering premultiplied texels is correct at glyph edges). */
void main()
{
  frag_color = texture(hud_image, v_uv);
}
