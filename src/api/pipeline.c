/* api layer: the mesher's steps from a label image to the extracted mesh (include/i2m/pipeline.h).
 *
 * Started by an MPI launcher, every rank has read the image and makes its distance transform,
 * then the dist layer refines in parallel (rank 0's threads build the coarse mesh; the ranks
 * refine the octree's subregions, each keeping what it refined) and each rank extracts the
 * tets it holds.  Every step that can fail agrees on the error across the ranks, so that all
 * of them end with the same error. */
#include "i2m/pipeline.h"

#include <stdlib.h>
#include <string.h>

/* The same step on every rank, its error agreed on. */
#define AGREE(p, call) I2M_CALL(i2m_par_agree((p)->par, (call)))

void i2m_pipeline_phase_begin(i2m_pipeline_t *p, const char *what)
{
  p->tphase = i2m_wtime();
  i2m_debug("i2m: %s", what);
}

void i2m_pipeline_phase_end(i2m_pipeline_t *p, int phase)
{
  p->phase_seconds[phase] = i2m_wtime() - p->tphase;
  i2m_debug("i2m: %s done in %.2f s; resident %.0f MB, peak %.0f MB", i2m_phase_name(phase), p->phase_seconds[phase],
            (double)i2m_current_rss_bytes() / 1048576.0, (double)i2m_peak_rss_bytes() / 1048576.0);
}

i2m_err_t i2m_pipeline_check_estimate(const i2m_par_t *par, const i2m_image_t *img, const i2m_pipeline_opts_t *opt)
{
  i2m_refine_estimate_t e;
  i2m_refine_estimate(img, &opt->params, &e);
  const double mine = e.bytes / par->size; /* (each rank holds its share of the mesh) */
  double limit = i2m_memory_limit_bytes() / par->local_size, given = opt->max_memory;
  if (given > 0) limit = given;
  i2m_debug("estimate: interface %.4g mm2, volume %.4g mm3, %.4g tets, %.4g MB per process (limit %.4g MB)",
            e.interface_mm2, e.volume_mm3, e.tets, mine / 1048576.0, limit / 1048576.0);
  I2M_CHECK(limit <= 0 || mine <= limit, I2M_ERR_MEMORY,
            "the mesh is estimated at %.3g million tets and %.3g GB per process (interface %.3g mm2 at delta %g mm), "
            "more than the %.3g GB %s: raise --delta or --size, or run on more processes",
            e.tets / 1e6, mine / 1073741824.0, e.interface_mm2, e.delta, limit / 1073741824.0,
            given > 0 ? "of --max-memory" : par->local_size > 1 ? "each process of this node may use" : "this process may use");
  return I2M_OK;
}

static i2m_threads_opts_t threads_opts(const i2m_pipeline_opts_t *o)
{
  return (i2m_threads_opts_t){o->threads, o->coarse_factor, o->pin, o->deterministic, o->depth};
}

static i2m_err_t refine(i2m_pipeline_t *p)
{
  const i2m_threads_opts_t to = threads_opts(&p->opt);
  if (!p->distributed) return i2m_par_agree(p->par, i2m_threads_refine(p->ref, &to, &p->team));
  const char *inject = getenv("I2M_INJECT_FAILURE"); /* (tests: a rank that fails in the middle of refinement) */
  i2m_dist_opts_t d = {to, p->opt.trace, inject ? atoi(inject) : -1, p->opt.spread_output};
  return i2m_dist_refine(p->par, p->ref, &d, &p->team, &p->dist); /* (agreed on inside) */
}

/* The optional sliver perturbation (the rules it applies read the grids: before they go). */
static i2m_err_t perturb_slivers(i2m_pipeline_t *p)
{
  const i2m_threads_opts_t to = threads_opts(&p->opt);
  i2m_err_t err;
  if (!p->distributed) {
    err = i2m_par_agree(p->par, i2m_threads_perturb_slivers(p->ref, &to, p->opt.sliver_angle, &p->slivers));
  } else {
    const i2m_dist_opts_t d = {to, NULL, -1, p->opt.spread_output};
    err = i2m_dist_perturb_slivers(p->par, p->ref, &d, p->opt.sliver_angle, &p->slivers); /* (agreed on inside) */
  }
  if (err == I2M_OK && p->distributed && p->opt.spread_output) /* (its tasks move cells) */
    err = i2m_dist_balance(p->par, p->ref, &p->dist);
  if (err != I2M_OK) return err;
  p->bands_before = p->slivers.bands_before; /* (the pass's first look at the mesh: this rank's tets) */
  i2m_par_sum_i64(p->par, p->bands_before.below, I2M_DIHEDRAL_NLOW);
  i2m_par_sum_i64(p->par, p->bands_before.above, I2M_DIHEDRAL_NHIGH);
  return I2M_OK;
}

/* The fragments' repair and the census ask the transform about the image; under MPI the
 * pieces of the whole mesh come from every rank's parts (and again once labels changed). */
static i2m_err_t fragments_and_census(i2m_pipeline_t *p)
{
  if (p->distributed) I2M_CALL(i2m_dist_pieces(p->par, p->ref, I2M_WHOLE_MIN_VOXELS));
  AGREE(p, i2m_refine_repair_fragments(p->ref));
  if (p->distributed) {
    i2m_refine_stats_t st;
    i2m_refine_get_stats(p->ref, &st);
    if (st.fragments) { /* (the same figure on every rank) */
      I2M_CALL(i2m_dist_exchange_ghosts(p->par, p->ref));
      I2M_CALL(i2m_dist_pieces(p->par, p->ref, I2M_WHOLE_MIN_VOXELS));
    }
  }
  AGREE(p, i2m_refine_census(p->ref, I2M_WHOLE_MIN_VOXELS, &p->pieces));
  return I2M_OK;
}

/* The order-independent checksum of the whole triangulation (one pass over it). */
static void checksum(i2m_pipeline_t *p)
{
  p->checksum = i2m_dt_checksum(i2m_refine_dt(p->ref), &p->working_tets);
  int64_t sums[2] = {(int64_t)p->checksum, p->working_tets}; /* (sums modulo 2^64) */
  i2m_par_sum_i64(p->par, sums, 2);
  p->checksum = (uint64_t)sums[0];
  p->working_tets = sums[1];
}

static i2m_err_t mesh_in_frame(i2m_pipeline_t *p, const i2m_refine_params_t *params)
{
  i2m_pipeline_phase_begin(p, "distance transform");
  I2M_CALL(i2m_dist_edt_create(p->par, p->img, &p->edt)); /* (each rank a share; agreed on inside) */
  if (p->edt->labels_packed) i2m_image_release_voxels(p->img); /* the transform answers label queries */
  i2m_pipeline_phase_end(p, I2M_PHASE_EDT);

  i2m_pipeline_phase_begin(p, "refinement");
  AGREE(p, i2m_refine_create(p->img, p->edt, params, &p->ref));
  I2M_CALL(refine(p));
  if (p->opt.sliver_angle > 0) {
    i2m_pipeline_phase_end(p, I2M_PHASE_REFINE);
    i2m_pipeline_phase_begin(p, "sliver perturbation");
    I2M_CALL(perturb_slivers(p));
  }
  if (p->opt.check) AGREE(p, i2m_dt_check(i2m_refine_dt(p->ref), true));
  i2m_refine_release_scratch(p->ref); /* the grids' memory, before extraction adds the mesh */
  i2m_pipeline_phase_end(p, p->opt.sliver_angle > 0 ? I2M_PHASE_SLIVERS : I2M_PHASE_REFINE);

  i2m_pipeline_phase_begin(p, "extraction");
  I2M_CALL(fragments_and_census(p));
  i2m_edt_destroy(&p->edt);
  i2m_image_release_voxels(p->img);
  if (p->opt.checksum) checksum(p);
  AGREE(p, i2m_refine_extract(p->ref, &p->mesh));
  i2m_refine_release_mesh(p->ref);
  AGREE(p, i2m_tetmesh_sort(p->mesh)); /* (the triangulation's memory gone first) */
  i2m_pipeline_phase_end(p, I2M_PHASE_EXTRACT);
  int64_t nt = p->mesh->nt;
  i2m_par_sum_i64(p->par, &nt, 1);
  I2M_CHECK(nt > 0, I2M_ERR_INPUT,
            "%s: the mesh is empty: the labelled region is smaller than what delta = %g mm can resolve; try a smaller --delta",
            p->img->path && *p->img->path ? p->img->path : "the image", i2m_refine_params(p->ref)->delta);
  return I2M_OK;
}

/* The image is meshed in a frame near its own corner (i2m_image_mesh_shift): its origin moves
 * there for the steps, and back; extraction returns world coordinates. */
i2m_err_t i2m_pipeline_mesh(i2m_pipeline_t *p)
{
  i2m_refine_params_t params = p->opt.params;
  const double origin[3] = {p->img->origin[0], p->img->origin[1], p->img->origin[2]};
  i2m_image_mesh_shift(p->img, params.shift);
  if (params.shift[0] != 0 || params.shift[1] != 0 || params.shift[2] != 0)
    i2m_debug("i2m: meshed in a frame shifted by (%.17g, %.17g, %.17g) mm", params.shift[0], params.shift[1], params.shift[2]);
  for (int a = 0; a < 3; a++) p->img->origin[a] -= params.shift[a];
  i2m_err_t err = mesh_in_frame(p, &params);
  memcpy(p->img->origin, origin, sizeof origin);
  return err;
}

void i2m_pipeline_free(i2m_pipeline_t *p)
{
  i2m_threads_report_free(&p->team);
  i2m_dist_report_free(&p->dist);
  i2m_free(&p->pieces);
  i2m_tetmesh_destroy(&p->mesh);
  i2m_refine_destroy(&p->ref);
  i2m_edt_destroy(&p->edt);
}
