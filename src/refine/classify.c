/* Refine layer: evaluation of the refinement rules on a tet (ARCHITECTURE §4).
 *
 * When a tet is created, the label at its circumcentre is cached (2 bytes); classify_level
 * then tells which list the tet belongs to, and classify_action, when the tet is popped,
 * computes the point to insert and a tet whose circumball holds it, following the priority
 * R1, R5/R6, R2, R3, R4.  Centres and radii are recomputed in double when needed. */
#include "refine_impl.h"

#include <string.h>

/* The centre, radius and voxel of the tet with these vertices (in this order). */
static I2M_INLINE void centre_of(const i2m_refine_t *r, const double *const x[4], tet_geom_t *g)
{
  if (i2m_tet_circumcenter(x[0], x[1], x[2], x[3], g->cc, &g->r2) != 0) {
    g->r2 = INFINITY;
    g->u[0] = g->u[1] = g->u[2] = NAN;
    g->vox = -1;
    return;
  }
  i2m_edt_world_to_k(r->edt, g->cc, g->u);
  g->vox = i2m_edt_voxel_k(r->edt, g->u);
}

void tet_centre(const i2m_refine_t *r, uint32_t t, tet_geom_t *g)
{
  const double *x[4];
  tet_points(r->dt, t, x);
  centre_of(r, x, g);
}

int centre_label(const i2m_refine_t *r, const double *const x[4])
{
  tet_geom_t g;
  centre_of(r, x, &g);
  return isfinite(g.r2) ? i2m_edt_label_k(r->edt, g.u, g.vox) : 0; /* (flat: 0, as tet_probe says) */
}

static bool in_box(const i2m_dt_t *dt, const double p[3]);
static bool volume_bad_at(const i2m_refine_t *r, const double *const x[4], const double cc[3], double r2, int lab);

int centre_label_volume(const i2m_refine_t *r, const double *const x[4], bool *volume_fires)
{
  tet_geom_t g;
  centre_of(r, x, &g);
  *volume_fires = false;
  if (!isfinite(g.r2)) return 0;
  const int label = i2m_edt_label_k(r->edt, g.u, g.vox);
  *volume_fires = label != 0 && in_box(r->dt, g.cc) && volume_bad_at(r, x, g.cc, g.r2, label);
  return label;
}

void tet_probe(const i2m_refine_t *r, uint32_t t, probe_kind_t kind, tet_geom_t *g)
{
  const i2m_dt_t *dt = r->dt;
  g->probe.d2 = INFINITY;
  if (!isfinite(g->r2)) { /* flat */
    g->label = kind == PROBE_NEW ? 0 : tinfo(dt, t)->label;
    return;
  }
  /* the closest point within the ball (all a new tet's classification asks), and when an
   * action is chosen within 2 delta too (R7 keeps track of the free vertices that close to
   * an interface); the probe skips the closest point beyond that reach */
  const double reach2 = kind == PROBE_NEW || g->r2 > r->four_delta2 ? g->r2 : r->four_delta2;
  if (kind != PROBE_CENTRE) i2m_edt_probe_k(r->edt, g->cc, g->u, g->vox, reach2, &g->probe);
  g->label = kind == PROBE_NEW ? g->probe.label : tinfo(dt, t)->label;
}

void tet_geom(const i2m_refine_t *r, uint32_t t, probe_kind_t kind, tet_geom_t *g)
{
  tet_centre(r, t, g);
  tet_probe(r, t, kind, g);
}

/* Size and ratio bounds at a point (world) with label index lab. */
static void local_bounds(const i2m_refine_t *r, const double c[3], int lab, double *size, double *ratio)
{
  double s = r->p.size, q = r->p.ratio;
  if (r->label_size && r->label_size[lab] < s) s = r->label_size[lab];
  if (r->p.nregions) {
    const double w[3] = {c[0] + r->p.shift[0], c[1] + r->p.shift[1], c[2] + r->p.shift[2]}; /* (regions: world) */
    for (int k = 0; k < r->p.nregions; k++) {
      const i2m_region_t *g = &r->p.regions[k];
      if (w[0] < g->lo[0] || w[0] > g->hi[0] || w[1] < g->lo[1] || w[1] > g->hi[1] || w[2] < g->lo[2] ||
          w[2] > g->hi[2])
        continue;
      if (g->size < s) s = g->size;
      if (g->ratio < q) q = g->ratio;
    }
  }
  *size = s * r->size_scale;
  *ratio = q;
}

/* R3 or R4 on an inside tet with vertices x, centre cc, squared radius r2 and label index lab. */
static bool volume_bad_at(const i2m_refine_t *r, const double *const x[4], const double cc[3], double r2, int lab)
{
  double size, ratio;
  local_bounds(r, cc, lab, &size, &ratio);
  if (r2 > size * size) return true;
  return r2 > ratio * ratio * i2m_tet_min_edge2(x[0], x[1], x[2], x[3]);
}

static bool volume_bad(const i2m_refine_t *r, uint32_t t, const tet_geom_t *ti)
{
  const double *x[4];
  tet_points(r->dt, t, x);
  return volume_bad_at(r, x, ti->cc, ti->r2, ti->label);
}

/* Which rule of R3/R4 fires (3 or 4), for the statistics. */
static int volume_rule(const i2m_refine_t *r, const tet_geom_t *ti)
{
  double size, ratio;
  local_bounds(r, ti->cc, ti->label, &size, &ratio);
  return ti->r2 > size * size ? 4 : 3;
}

/* A restricted facet (face i of t) that R6 (returns 6) or R5 (returns 5) wants refined; -1
 * when the tet across it cannot be read here (another rank's, or outside the cells of the
 * worker's task: the facet is judged where both sides are held). */
static int facet_bad(const i2m_refine_worker_t *wk, uint32_t t, uint32_t i)
{
  const i2m_refine_t *r = wk->r;
  const i2m_dt_t *dt = r->dt;
  uint32_t n = dt->tn[4 * t + i];
  if (n == I2M_DT_NONE) return 0; /* the box hull: far from the image */
  if (n == I2M_DT_REMOTE) return -1;
  if (tinfo(dt, n >> 2)->label == tinfo(dt, t)->label) return 0; /* (a neighbour of a zone's tet is nobody else's) */
  if (wk->ctx.block && !i2m_dt_block_holds(dt, wk->ctx.block, n >> 2)) return -1;
  const uint32_t *v = dt->tv + 4 * (size_t)t;
  const double *p[3];
  int k = 0;
  for (uint32_t j = 0; j < 4; j++) {
    if (j == i) continue;
    if (dt->vkind[v[j]] != I2M_VK_SURFACE) return 6;
    p[k++] = i2m_dt_xyz(dt, v[j]);
  }
  return facet_angle_bad(r, p) ? 5 : 0;
}

bool facet_angle_bad(const i2m_refine_t *r, const double *const p[3])
{
  /* R5: smallest angle < theta  <=>  l_min^2 |u x w|^2 < sin^2(theta) |u|^2 |w|^2 |u - w|^2 */
  double u[3], w[3], x[3];
  for (int a = 0; a < 3; a++) {
    u[a] = p[1][a] - p[0][a];
    w[a] = p[2][a] - p[0][a];
    x[a] = p[2][a] - p[1][a];
  }
  double lu = u[0] * u[0] + u[1] * u[1] + u[2] * u[2];
  double lw = w[0] * w[0] + w[1] * w[1] + w[2] * w[2];
  double lx = x[0] * x[0] + x[1] * x[1] + x[2] * x[2];
  double cx = u[1] * w[2] - u[2] * w[1], cy = u[2] * w[0] - u[0] * w[2], cz = u[0] * w[1] - u[1] * w[0];
  double area2 = cx * cx + cy * cy + cz * cz;
  double lmin = lu < lw ? (lu < lx ? lu : lx) : (lw < lx ? lw : lx);
  return lmin * area2 < r->sin2_facet * lu * lw * lx;
}

/* Ball of t meets an interface: the closest interface point z to its centre, the patch it
 * lies on, and the squared distance. */
static bool ball_meets_interface(const tet_geom_t *ti, double z[3], uint32_t *patch, double *d2)
{
  *d2 = ti->probe.d2;
  if (!isfinite(*d2)) return false;
  memcpy(z, ti->probe.z, 3 * sizeof *z);
  *patch = patch_key(ti->probe.pair[0], ti->probe.pair[1]);
  return *d2 <= ti->r2;
}

/* Tiles: a tet of any label whose centre lies in the labelled block, or in a shell around it
 * (so that no huge tet outside borders a cavity of the block), and whose radius exceeds the
 * background bound (so that every cavity fits a tile's zone). */
static bool too_big(const i2m_refine_t *r, const tet_geom_t *ti)
{
  if (!(ti->r2 > r->background_size2)) return false;
  for (int a = 0; a < 3; a++)
    if (!(ti->cc[a] >= r->block_lo[a] - r->background_shell && ti->cc[a] <= r->block_hi[a] + r->background_shell))
      return false;
  return true;
}

static bool in_box(const i2m_dt_t *dt, const double p[3])
{
  for (int a = 0; a < 3; a++)
    if (!(p[a] > dt->box_lo[a] && p[a] < dt->box_hi[a])) return false;
  return true;
}

/* R1's spacing test on the tet's own vertices: is one a surface vertex of the same patch
 * within delta of z?  (Near a sampled surface one of them usually is.) */
static bool own_vertex_near(const i2m_refine_t *r, uint32_t t, const double z[3], uint32_t patch)
{
  const i2m_dt_t *dt = r->dt;
  const uint32_t *v = dt->tv + 4 * (size_t)t;
  for (int i = 0; i < 4; i++)
    if (dt->vkind[v[i]] == I2M_VK_SURFACE && r->surf.tag[v[i]] == patch && i2m_dist2(i2m_dt_xyz(dt, v[i]), z) < r->delta2)
      return true;
  return false;
}

/* R2 (a ball meeting an interface, radius of 2 delta or more), R3 or R4 (a labelled tet's ratio
 * or size), for a tet whose centre lies in the box: the rules that insert its circumcentre. */
static bool centre_rule_fires(const i2m_refine_t *r, uint32_t t, const tet_geom_t *ti, bool meets)
{
  return (meets && ti->r2 >= r->four_delta2) || (ti->label != 0 && volume_bad(r, t, ti));
}

int classify_level(i2m_refine_worker_t *w, uint32_t t, const tet_geom_t *ti)
{
  const i2m_refine_t *r = w->r;
  double z[3], d2;
  uint32_t patch;
  if (too_big(r, ti)) return LEVEL_SURFACE; /* (deterministic mode: first, as it keeps cavities in the zones) */
  if (ball_meets_interface(ti, z, &patch, &d2)) {
    if (!own_vertex_near(r, t, z, patch)) return LEVEL_SURFACE; /* R1 unless the grid finds a vertex: when popped */
    if (ti->r2 >= r->four_delta2 && in_box(r->dt, ti->cc)) return LEVEL_R2;
  }
  for (uint32_t i = 0; i < 4; i++)
    if (facet_bad(w, t, i)) return LEVEL_SURFACE; /* (-1: perhaps; judged when popped) */
  if (ti->label != 0 && in_box(r->dt, ti->cc) && volume_bad(r, t, ti)) return LEVEL_VOLUME;
  return -1;
}

bool classify_nothing_to_do(i2m_refine_worker_t *w, uint32_t t)
{
  const i2m_refine_t *r = w->r;
  tet_geom_t g;
  tet_centre(r, t, &g);
  tet_probe(r, t, PROBE_CLOSEST, &g);
  if (too_big(r, &g)) return false;
  double z[3], d2;
  uint32_t patch;
  const bool meets = ball_meets_interface(&g, z, &patch, &d2);
  /* a surface vertex found stays (refinement removes only free vertices): R1 will not fire */
  if (meets && !own_vertex_near(r, t, z, patch) && !vgrid_has_within(&r->surf, r->dt, z, r->delta, patch)) return false;
  for (uint32_t i = 0; i < 4; i++)
    if (facet_bad(w, t, i)) return false;
  return !in_box(r->dt, g.cc) || !centre_rule_fires(r, t, &g, meets);
}

/* The surface centre of facet i of t: where the Voronoi edge between the two circumcentres
 * crosses the interface; the seed is whichever of the two tets holds it in its circumball. */
static bool facet_action(const i2m_refine_t *r, uint32_t t, uint32_t i, action_t *a)
{
  const i2m_dt_t *dt = r->dt;
  uint32_t u = dt->tn[4 * t + i] >> 2;
  tet_geom_t gt, gu;
  tet_geom(r, t, PROBE_CENTRE, &gt);
  tet_geom(r, u, PROBE_CENTRE, &gu);
  if (!isfinite(gt.r2) || !isfinite(gu.r2)) return false;
  int la, lb;
  i2m_edt_bisect(r->edt, gt.cc, gu.cc, r->bisect_tol, a->p, &la, &lb);
  if (la == lb || !in_box(dt, a->p)) return false;
  a->patch = patch_key(la, lb);
  i2m_gidx_t none = INT64_MAX; /* a fresh point: its id is larger than every vertex's */
  const uint32_t *candidates[2] = {dt->tv + 4 * (size_t)t, dt->tv + 4 * (size_t)u};
  for (int k = 0; k < 2; k++) {
    const uint32_t *v = candidates[k];
    if (i2m_insphere_sos(i2m_dt_xyz(dt, v[0]), i2m_dt_xyz(dt, v[1]), i2m_dt_xyz(dt, v[2]), i2m_dt_xyz(dt, v[3]), a->p,
                         i2m_dt_gid(dt, v[0]), i2m_dt_gid(dt, v[1]), i2m_dt_gid(dt, v[2]), i2m_dt_gid(dt, v[3]),
                         none) > 0) {
      a->seed = k == 0 ? t : u;
      return true;
    }
  }
  return false;
}

int classify_action(i2m_refine_worker_t *w, uint32_t t, action_t *a, uint32_t skip)
{
  const i2m_refine_t *r = w->r;
  const i2m_dt_t *dt = r->dt;
  tet_geom_t g;
  const tet_geom_t *ti = &g;
  tet_centre(r, t, &g);
  if (!tiles_ball_fits(w, g.cc, g.r2)) return -1; /* its cavity would most likely leave the zone */
  tet_probe(r, t, PROBE_CLOSEST, &g);
  memset(a, 0, sizeof *a);
  a->seed = t;
  a->level = LEVEL_SURFACE;
  double z[3], d2;
  uint32_t patch;
  bool meets = ball_meets_interface(ti, z, &patch, &d2);
  a->dist2 = d2;
  if (too_big(r, ti) && in_box(dt, ti->cc) && !(skip & (1u << 2 | 1u << 3 | 1u << 4))) { /* first: see classify_level */
    memcpy(a->p, ti->cc, sizeof a->p);
    a->kind = I2M_VK_FREE;
    a->rule = 4;
    return 1;
  }
  /* R1, unless a surface vertex of the patch lies within delta of z: the tet's own first,
   * then the grid (which, near another tile's zone, may change meanwhile) */
  bool r1 = meets && !(skip & (1u << 1)) && !own_vertex_near(r, t, z, patch);
  if (r1 && !tiles_zone_holds(w, z)) return -1;
  if (r1 && !vgrid_has_within(&r->surf, dt, z, r->delta, patch)) {
    memcpy(a->p, z, sizeof z);
    a->patch = patch;
    a->kind = I2M_VK_SURFACE;
    a->rule = 1;
    return 1;
  }
  for (uint32_t i = 0; i < 4 && !(skip & (1u << 5 | 1u << 6)); i++) { /* R5, R6 */
    int rule = facet_bad(w, t, i);
    if (rule < 0) return -1; /* where both sides are held */
    if (!rule) continue;
    if (facet_action(r, t, i, a)) {
      a->kind = I2M_VK_SURFACE;
      a->rule = rule;
      return 1;
    }
    w->st.failed++; /* no surface centre could be placed: counted, never silent */
  }
  if (!in_box(dt, ti->cc) || (skip & (1u << 2 | 1u << 3 | 1u << 4))) return 0;
  if (centre_rule_fires(r, t, ti, meets)) { /* R2, R3, R4 */
    memcpy(a->p, ti->cc, sizeof a->p);
    a->kind = I2M_VK_FREE;
    a->rule = (meets && ti->r2 >= r->four_delta2) ? 2 : volume_rule(r, ti);
    a->level = a->rule == 2 ? LEVEL_R2 : LEVEL_VOLUME;
    return 1;
  }
  return 0;
}
