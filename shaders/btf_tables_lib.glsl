/* BTF tables packed into two textures (btf_addon/core/codecs/packed.py): every table flattened and laid
 * out row by row in R32F textures TABLE_WIDTH texels wide, one of integers (stored exactly as
 * floats, all below 2^24) and one of floats. The first texels of each hold a header of sizes and
 * table offsets, so no push constants are spent on the layout.
 * Samplers: btf_int_tables, btf_float_tables (both sampler2D). */

/* TABLE_WIDTH, the header slots (H_*: integer stream, F_*: float stream) and the codec ids
 * (CODEC_*) are not written here: btf_addon/core/codecs/packed.py defines the layout once and
 * btf_addon/gl/interface.py passes it to every shader build as defines (packed.defines()). */
#if !defined(TABLE_WIDTH) || !defined(H_CODEC) || !defined(F_VALUE_SCALE) || !defined(CODEC_MLVQ)
#error packed-layout defines missing: build through btf_addon/gl/interface.py
#endif

int itab(int i)
{
  return int(texelFetch(btf_int_tables, ivec2(i % TABLE_WIDTH, i / TABLE_WIDTH), 0).r);
}

float ftab(int i)
{
  return texelFetch(btf_float_tables, ivec2(i % TABLE_WIDTH, i / TABLE_WIDTH), 0).r;
}
