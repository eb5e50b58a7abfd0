/* BTF tables packed into two textures (btf_addon/core/packed.py): every table flattened and laid
 * out row by row in R32F textures TABLE_WIDTH texels wide, one of integers (stored exactly as
 * floats, all below 2^24) and one of floats. The first texels of each hold a header of sizes and
 * table offsets, so no push constants are spent on the layout.
 * Samplers: btf_int_tables, btf_float_tables (both sampler2D). */

#define TABLE_WIDTH 4096

int itab(int i)
{
  return int(texelFetch(btf_int_tables, ivec2(i % TABLE_WIDTH, i / TABLE_WIDTH), 0).r);
}

float ftab(int i)
{
  return texelFetch(btf_float_tables, ivec2(i % TABLE_WIDTH, i / TABLE_WIDTH), 0).r;
}

/* Integer header slots (keep in sync with btf_addon/core/packed.py: INT_HEADER). */
#define H_CODEC 1
#define H_N_BETA 2
#define H_N_ALPHA 3
#define H_N_THETA 4
#define H_N_PHI 5
#define H_WIDTH 6
#define H_HEIGHT 7
#define H_ROWS_OFFSET 8
#define H_COLS_OFFSET 9
#define H_HDR 10
#define H_COS_BETA 11
#define H_INDEX_AB 12
#define H_PDF2_COLOURS 13
#define H_PDF2_SLICES 14
#define H_PDF2_INDICES 15
#define H_PDF3_SLICES 16
#define H_PDF4_SLICES 17
#define H_PDF6_SLICES 18
#define H_F_PDF1 19
#define H_F_AB 20
#define H_F_PDF2_SCALE 21
#define H_F_PDF3_SCALE 22
#define H_F_PDF4_SCALE 23
#define H_F_PDF6_SCALE 24
#define H_F_BETA 25
/* dense codec */
#define H_N_LIGHTS 26
#define H_F_DATA 27
#define H_N_VIEW_RINGS 28
#define H_F_VIEW_THETA 29
#define H_VIEW_OFFSETS 30
#define H_N_LIGHT_RINGS 31
#define H_F_LIGHT_THETA 32
#define H_LIGHT_OFFSETS 33
/* Float header slots. */
#define F_VALUE_SCALE 0
#define F_HDR_VALUE 1
#define F_ALBEDO 2 /* 3 floats */
#define F_ALPHA2 5
#define F_METALLIC 6
#define F_DIFFUSE_ROUGHNESS 7
#define F_SPECULAR_F0 8

#define CODEC_MLVQ 1
#define CODEC_LAMBERTIAN 2
#define CODEC_GGX 3
#define CODEC_DENSE 4
#define CODEC_PRINCIPLED 5
