/* One light path of the Sampled mode from a surface point: what render_env_mis adds per sample
 * once its camera ray has met a surface, and what the light bake (render_direct.cl bake_light)
 * adds per sample at a bake point. One definition, so a bake holds exactly the light F12
 * computes: next-event estimation of the World (its sun and the lobe window at a glossy first
 * vertex), Blender's lights, a direction from the BTF's sampling, MIS, bounces, Russian
 * roulette and Clamp Indirect.
 *
 * Included by render_direct.cl after the World's helpers (env_lookup … env_pdf,
 * btf_env_window.h) and clamp_indirect, which it calls. */
#ifndef BTF_PATH_H
#define BTF_PATH_H

/* What a path reads besides its own point: the scene, the World and its sampling tables, and
 * the path's limits; filled once per work item. */
typedef struct {
  __global const float *bounds;
  __global const int *links;
  __global const float *corners;
  __global const int *tri_material;
  __global const float *ints;
  __global const float *floats;
  __global const int *material_offsets;
  __global const float *material_params;
  float eps;
  __global const float *env;
  int env_w, env_h;
  float2 env_params;
  __global const float *scene_lights;
  int scene_light_count;
  __global const float *row_cdf, *col_cdf, *row_pdf, *col_pdf;
  __global const float *sun_cdf;
  __global const int *sun_pixels;
  __global const float *sun_probability;
  int sun_count;
  float sun_share;
  __global const float *window_row_pdf, *window_cdf;
  int window_block;
  int max_bounces;
  float indirect_limit;
} PathScene;

/* Adds to *sum the light reaching the viewer from `cur` (cur.wo is the direction towards it)
 * along one path drawn with `smp`: the first vertex's light as it comes, the rest clamped at
 * Clamp Indirect. The additions happen in render_env_mis's order of before (the same float
 * sums, so the same images bit for bit). */
inline void path_light(const PathScene *ps, SurfacePoint cur, Sampler *smp, float3 *sum)
{
  /* The names the path's code has always used. */
  __global const float *bounds = ps->bounds, *corners = ps->corners;
  __global const int *links = ps->links, *tri_material = ps->tri_material;
  __global const float *ints = ps->ints, *floats = ps->floats;
  __global const int *material_offsets = ps->material_offsets;
  __global const float *material_params = ps->material_params;
  float eps = ps->eps;
  __global const float *env = ps->env;
  int env_w = ps->env_w, env_h = ps->env_h;
  float2 env_params = ps->env_params;
  float rotation = env_params.x;
  __global const float *scene_lights = ps->scene_lights;
  int scene_light_count = ps->scene_light_count;
  __global const float *row_cdf = ps->row_cdf, *col_cdf = ps->col_cdf;
  __global const float *row_pdf = ps->row_pdf, *col_pdf = ps->col_pdf;
  __global const float *sun_cdf = ps->sun_cdf;
  __global const int *sun_pixels = ps->sun_pixels;
  __global const float *sun_probability = ps->sun_probability;
  int sun_count = ps->sun_count;
  float sun_share = ps->sun_share;
  __global const float *window_row_pdf = ps->window_row_pdf, *window_cdf = ps->window_cdf;
  int window_block = ps->window_block;
  int max_bounces = ps->max_bounces;
  float indirect_limit = ps->indirect_limit;
  float3 throughput = (float3)(1.0f);
  float3 indirect = (float3)(0.0f); /* light after the first bounce, clamped at the end */
  for (int bounce = 0; cur.wo.z > 0.0f; bounce++) {
    float3 *light = bounce == 0 ? sum : &indirect;
    __global const float *I = ints + material_offsets[2 * cur.material];
    __global const float *F = floats + material_offsets[2 * cur.material + 1];
    float exposure = cur.exposure;
    int pixel;
    int table = bsdf_table(I, cur.wo); /* the BTF's sampling table for this view, if any */
    /* The map's sun (envmap.py Environment.sun_tables; sun_count > 0) is drawn on its own
     * where a small bright source does most harm drawn from the whole table: at the camera's
     * vertex on a glossy lobe, where each rare find of the sun is a bright sample in its
     * highlight (1b below). Elsewhere the first draw picks the sun or the rest of the map by
     * the sun's share of the compensated weight: the two tables then make the compensated
     * table (mis_tables) exactly, at one draw's cost. */
    bool split = sun_count > 0 && bounce == 0 &&
                 (table > 0 || ggx_lobe_probability(I, F) > 0.0f);
    float share = sun_count > 0 && !split ? sun_share : 0.0f;
    /* 1. Next-event estimation: a direction from the environment's distribution. */
#if !HAS_ENVIRONMENT /* black: it adds 0; its random numbers are still drawn (same image) */
    (void)next_2d(smp);
#else
    /* The lobe window (include/btf_env_window.h; 1c. below): at a split vertex whose light
     * is mostly a GGX lobe's (the GGX codec, a metallic Principled), where the map has one,
     * the table drawn beside the sun restricted to the lobe's neighbourhood. */
    LobeWindow win;
    win.mass = 0.0f;
    if (split && window_block > 0 && table == 0 && ggx_lobe_probability(I, F) >= 0.9f) {
      float3 mirror = 2.0f * cur.wo.z * cur.n -
                      (cur.wo.x * cur.t + cur.wo.y * cur.b + cur.wo.z * cur.n);
      win = lobe_window(mirror, sqrt(FTAB(F_ALPHA2)), window_row_pdf, window_cdf,
                        window_block, env_w, env_h, rotation);
    }
    {
      float2 u = next_2d(smp);
      float sin_t;
      /* (u.x − 0) / (1 − 0) is u.x: a map without a sun draws exactly as before */
      float3 dir = u.x < share ? sun_draw((float2)(u.x / share, u.y), sun_cdf, sun_pixels,
                                          sun_count, env_w, env_h, rotation, &pixel, &sin_t)
                               : table_draw((float2)((u.x - share) / (1.0f - share), u.y),
                                            row_cdf, col_cdf, env_w, env_h, rotation, &pixel,
                                            &sin_t);
      /* the density this draw was made with, from its own pixel: no round trip through
       * env_pdf's atan2 and acos (the same value up to rounding at pixel edges) */
      float pdf_light = next_event_density(
          table_density(row_pdf, col_pdf, env_w, env_h, pixel, sin_t), sun_probability, env_w,
          env_h, pixel, sin_t, share);
      float pdf_sun =
          split ? pixel_density(sun_probability[pixel], env_w, env_h, sin_t) : 0.0f;
      float3 wi = to_frame(&cur, dir);
      float pdf_bsdf = bsdf_pdf_at(I, F, table, wi, cur.wo);
      bool visible = wi.z > 0.0f && pdf_light > 0.0f;
#if HAS_SHADOWS
      visible = visible && unoccluded(cur.start, dir, eps, INFINITY, bounds, links, corners);
#endif
      if (visible) {
        float3 value = btf_mapped(I, F, &cur, wi);
        float pdf_window = lobe_window_density(&win, window_block, env_w, env_h, pixel,
                                               pdf_light);
        float weight = power_weight(pdf_light, pdf_bsdf, pdf_sun, pdf_window);
        *light += throughput * exposure * value * vload3(0, env + 4 * pixel) *
                  env_params.y * (weight / pdf_light);
      }
    }
    /* 1b. The sun on its own: a smooth term of the highlight instead of rare bright draws. */
    if (split) {
      int sun;
      float sin_t;
      float3 dir = sun_draw(next_2d(smp), sun_cdf, sun_pixels, sun_count, env_w, env_h,
                            rotation, &sun, &sin_t);
      float pdf_sun = pixel_density(sun_probability[sun], env_w, env_h, sin_t);
      float3 wi = to_frame(&cur, dir);
      bool visible = wi.z > 0.0f && pdf_sun > 0.0f;
#if HAS_SHADOWS
      visible = visible && unoccluded(cur.start, dir, eps, INFINITY, bounds, links, corners);
#endif
      if (visible) {
        float pdf_light = table_density(row_pdf, col_pdf, env_w, env_h, sun, sin_t);
        float pdf_bsdf = bsdf_pdf_at(I, F, table, wi, cur.wo);
        /* the window draws from the table beside the sun: 0 on the sun's pixels */
        float weight = power_weight(pdf_sun, pdf_light, pdf_bsdf, 0.0f);
        *light += throughput * exposure * btf_mapped(I, F, &cur, wi) *
                  vload3(0, env + 4 * sun) * env_params.y * (weight / pdf_sun);
      }
    }
    /* 1c. The lobe window: the map's light where a narrow lobe reflects it. */
    if (win.mass > 0.0f) {
      int wp;
      float sin_t;
      float3 dir = lobe_window_draw(&win, next_2d(smp), window_cdf, row_pdf, col_cdf,
                                    window_block, env_w, env_h, rotation, &wp, &sin_t);
      float pdf_light = table_density(row_pdf, col_pdf, env_w, env_h, wp, sin_t);
      float pdf_window = pdf_light / win.mass;
      float3 wi = to_frame(&cur, dir);
      bool visible = wi.z > 0.0f && pdf_window > 0.0f;
#if HAS_SHADOWS
      visible = visible && unoccluded(cur.start, dir, eps, INFINITY, bounds, links, corners);
#endif
      if (visible) {
        /* a pixel of the table beside the sun is none of the sun's: its density there is 0 */
        float pdf_bsdf = bsdf_pdf_at(I, F, table, wi, cur.wo);
        float weight = power_weight(pdf_window, pdf_light, pdf_bsdf, 0.0f);
        *light += throughput * exposure * btf_mapped(I, F, &cur, wi) *
                  vload3(0, env + 4 * wp) * env_params.y * (weight / pdf_window);
      }
    }
#endif
    *light += throughput * exposure * blender_lights(&cur, I, F, scene_lights,
                                                      scene_light_count, eps, bounds, links,
                                                      corners, smp);
    /* 2. A direction from the BTF's sampling (include/btf_sampling.h): it either reaches the
     * World (MIS-weighted against the environment sample above) or, within the bounce
     * limit, continues the path. */
    float2 uc = next_2d(smp);
    float pdf_bsdf;
    float3 lo = bsdf_sample_at(I, F, table, cur.wo, rand01(&smp->rng), uc, &pdf_bsdf);
    if (!(pdf_bsdf > 0.0f) || lo.z <= 0.0f) {
      break;
    }
    float3 dir = lo.x * cur.t + lo.y * cur.b + lo.z * cur.n;
    float3 value = btf_mapped(I, F, &cur, lo);
    float3 step = throughput * exposure * value / pdf_bsdf;
    float th = 0.0f, uh = 0.0f, vh = 0.0f;
    int hit = -1;
#if HAS_SHADOWS /* surfaces that can occlude each other can also reflect each other */
    hit = trace(cur.start, dir, eps, INFINITY, bounds, links, corners, false, &th, &uh, &vh);
#endif
    if (hit < 0) {
#if HAS_ENVIRONMENT
      float sin_t;
      float map = env_pdf(row_pdf, col_pdf, env_w, env_h, rotation, dir, &pixel, &sin_t);
      float pdf_light =
          next_event_density(map, sun_probability, env_w, env_h, pixel, sin_t, share);
      float pdf_sun =
          split ? pixel_density(sun_probability[pixel], env_w, env_h, sin_t) : 0.0f;
      float pdf_window = lobe_window_density(&win, window_block, env_w, env_h, pixel, map);
      float weight = power_weight(pdf_bsdf, pdf_light, pdf_sun, pdf_window);
      *light += step * vload3(0, env + 4 * pixel) * env_params.y * weight;
#endif
      break;
    }
    if (bounce >= max_bounces) {
      break; /* the World is blocked and the path may not go further */
    }
    cur = surface_point(cur.start, dir, th, uh, vh, hit, corners, tri_material, material_params,
                        eps);
    throughput = step;
    if (bounce >= 2) { /* Russian roulette keeps long paths unbiased and cheap */
      float keep = fmin(fmax(throughput.x, fmax(throughput.y, throughput.z)), 0.95f);
      if (rand01(&smp->rng) >= keep) {
        break;
      }
      throughput /= keep;
    }
  }
  *sum += clamp_indirect(indirect, indirect_limit);
}

#endif
