/* cli layer: bin/i2m, the image-to-mesh driver: read, distance transform, refinement,
 * extraction, write, report.  The only place that calls exit codes.
 *
 * Started by an MPI launcher (mpirun, mpiexec, srun), every rank reads the image and makes its
 * distance transform, then the dist layer refines in parallel (rank 0's threads build the
 * coarse mesh; the ranks refine the octree's subregions, each keeping what it refined); each
 * rank extracts the tets it holds and the writer either writes them as pieces (.pvtu) or
 * stitches them on rank 0.  Every step that can fail agrees on the error across the ranks,
 * so that all of them end with the same exit code and rank 0 prints the one message. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "i2m/dist.h"
#include "i2m/edt.h"
#include "i2m/io.h"
#include "i2m/quality.h"
#include "i2m/refine.h"
#include "i2m/report.h"
#include "i2m/threads.h"
#include "options.h"

typedef struct {
  const i2m_par_t *par;
  bool distributed;            /* started under MPI: the dist layer refines */
  cli_options_t opt;
  i2m_image_t *img;
  i2m_edt_t *edt;
  i2m_refine_t *ref;
  i2m_tetmesh_t *mesh;
  i2m_label_pieces_t *pieces;  /* per label: image components and mesh pieces */
  i2m_quality_t quality;
  i2m_threads_report_t team;
  i2m_dist_report_t dist;
  i2m_report_t rep;
  double t0, tphase;
} run_t;

static void phase_begin(run_t *r, const char *what)
{
  r->tphase = i2m_wtime();
  i2m_debug("i2m: %s", what);
}
static void phase_end(run_t *r, int phase)
{
  r->rep.phase_seconds[phase] = i2m_wtime() - r->tphase;
  i2m_debug("i2m: %s done in %.2f s; resident %.0f MB, peak %.0f MB", i2m_phase_name(phase), r->rep.phase_seconds[phase],
            (double)i2m_current_rss_bytes() / 1048576.0, (double)i2m_peak_rss_bytes() / 1048576.0);
}

/* How the mesh is written: the writers' defaults, changed by the options. */
static i2m_write_opts_t write_opts(const run_t *r)
{
  i2m_write_opts_t wo = i2m_write_opts_default();
  (void)r;
  return wo;
}

/* Every large image component the mesh splits, on stderr (even with --quiet: the mesh is
 * then not what the user expects of it). */
static void warn_split_components(const run_t *r)
{
  for (int l = 1; l < r->img->nlabels; l++) {
    const i2m_label_pieces_t *p = &r->pieces[l];
    if (p->split_components)
      fprintf(stderr, "i2m: warning: label %lld: %lld of its %lld image components of >= %d voxels come out in several pieces\n",
              (long long)p->value, (long long)p->split_components, (long long)p->large_components, I2M_WHOLE_MIN_VOXELS);
  }
}

/* The same step on every rank, its error agreed on. */
#define AGREE(r, call) I2M_CALL(i2m_par_agree((r)->par, (call)))

static i2m_err_t refine(run_t *r)
{
  cli_options_t *o = &r->opt;
  i2m_threads_opts_t to = {o->threads, o->coarse_factor, !o->no_pin, o->deterministic != 0, o->depth};
  if (!r->distributed) return i2m_threads_refine(r->ref, &to, &r->team);
  const char *inject = getenv("I2M_INJECT_FAILURE"); /* (tests: a rank that fails in the middle of refinement) */
  i2m_dist_opts_t d = {to, o->trace, inject ? atoi(inject) : -1};
  return i2m_dist_refine(r->par, r->ref, &d, &r->team, &r->dist);
}

/* The run's size estimated before any work: refused when it cannot fit in memory. */
static i2m_err_t check_estimate(run_t *r)
{
  i2m_refine_estimate_t e;
  i2m_refine_estimate(r->img, &r->opt.params, &e);
  const i2m_par_t *par = r->par;
  const double mine = e.bytes / par->size; /* (each rank holds its share of the mesh) */
  double limit = i2m_memory_limit_bytes() / par->local_size, given = r->opt.max_memory;
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

static i2m_err_t run_mesher(run_t *r)
{
  cli_options_t *o = &r->opt;
  phase_begin(r, "reading the image");
  i2m_image_read_opts_t ro = {.allow_external_data = o->allow_external_data != 0, .header_only = true};
  AGREE(r, i2m_image_read_with(o->input, &ro, &r->img, NULL)); /* (the options checked before the voxels are read) */
  AGREE(r, i2m_refine_params_check_geometry(&o->params, r->img));
  i2m_image_destroy(&r->img);
  ro.header_only = false;
  AGREE(r, i2m_image_read_with(o->input, &ro, &r->img, NULL));
  AGREE(r, i2m_refine_params_check(&o->params, r->img));
  AGREE(r, check_estimate(r));
  phase_end(r, I2M_PHASE_READ);

  phase_begin(r, "distance transform");
  AGREE(r, i2m_edt_create(r->img, &r->edt));
  if (r->edt->labels_packed) i2m_image_release_voxels(r->img); /* the transform answers label queries */
  phase_end(r, I2M_PHASE_EDT);

  phase_begin(r, "refinement");
  AGREE(r, i2m_refine_create(r->img, r->edt, &o->params, &r->ref));
  i2m_err_t err = refine(r);
  if (r->distributed) I2M_CALL(err); /* (agreed on inside) */
  else AGREE(r, err);
  if (o->sliver_angle > 0) { /* (the rules it applies read the grids: before they go) */
    phase_end(r, I2M_PHASE_REFINE);
    phase_begin(r, "sliver perturbation");
    i2m_threads_opts_t to = {o->threads, o->coarse_factor, !o->no_pin, o->deterministic != 0, o->depth};
    if (r->distributed) {
      const i2m_dist_opts_t d = {to, NULL, -1};
      I2M_CALL(i2m_dist_perturb_slivers(r->par, r->ref, &d, o->sliver_angle, &r->rep.slivers)); /* (agreed on inside) */
    } else {
      AGREE(r, i2m_threads_perturb_slivers(r->ref, &to, o->sliver_angle, &r->rep.slivers));
    }
    r->rep.sliver_angle = o->sliver_angle;
  }
  if (o->check) AGREE(r, i2m_dt_check(i2m_refine_dt(r->ref), true));
  i2m_refine_release_scratch(r->ref); /* the grids' memory, before extraction adds the mesh */
  phase_end(r, o->sliver_angle > 0 ? I2M_PHASE_SLIVERS : I2M_PHASE_REFINE);

  phase_begin(r, "extraction");
  /* the fragments' repair and the census ask the transform about the image; under MPI the
   * pieces of the whole mesh come from every rank's parts (and again once labels changed) */
  if (r->distributed) I2M_CALL(i2m_dist_pieces(r->par, r->ref, I2M_WHOLE_MIN_VOXELS));
  AGREE(r, i2m_refine_repair_fragments(r->ref));
  if (r->distributed) {
    i2m_refine_stats_t st;
    i2m_refine_get_stats(r->ref, &st);
    if (st.fragments) { /* (the same figure on every rank) */
      I2M_CALL(i2m_dist_exchange_ghosts(r->par, r->ref));
      I2M_CALL(i2m_dist_pieces(r->par, r->ref, I2M_WHOLE_MIN_VOXELS));
    }
  }
  AGREE(r, i2m_refine_census(r->ref, I2M_WHOLE_MIN_VOXELS, &r->pieces));
  if (r->par->rank == 0) warn_split_components(r);
  i2m_edt_destroy(&r->edt);
  i2m_image_release_voxels(r->img);
  if (o->report) { /* (only the JSON report gives it: one pass over the whole triangulation) */
    r->rep.checksum = i2m_dt_checksum(i2m_refine_dt(r->ref), &r->rep.working_tets);
    int64_t sums[2] = {(int64_t)r->rep.checksum, r->rep.working_tets}; /* (sums modulo 2^64) */
    i2m_par_sum_i64(r->par, sums, 2);
    r->rep.checksum = (uint64_t)sums[0];
    r->rep.working_tets = sums[1];
  }
  AGREE(r, i2m_refine_extract(r->ref, &r->mesh));
  i2m_refine_release_mesh(r->ref);
  phase_end(r, I2M_PHASE_EXTRACT);
  int64_t nt = r->mesh->nt;
  i2m_par_sum_i64(r->par, &nt, 1);
  I2M_CHECK(nt > 0, I2M_ERR_INPUT,
            "%s: the mesh is empty: the labelled region is smaller than what delta = %g mm can resolve; try a smaller --delta",
            o->input, i2m_refine_params(r->ref)->delta);

  phase_begin(r, "writing the mesh");
  const i2m_write_opts_t wo = write_opts(r);
  I2M_CALL(i2m_mesh_write_par(r->par, &r->mesh, o->output, &wo)); /* (agreed on inside) */
  phase_end(r, I2M_PHASE_WRITE);
  return I2M_OK;
}

static i2m_err_t report(run_t *r)
{
  i2m_report_t *rep = &r->rep;
  const i2m_refine_params_t *p = i2m_refine_params(r->ref);
  const bool whole = r->par->size == 1 || i2m_format_from_path(r->opt.output) != I2M_FORMAT_PVTU;
  phase_begin(r, "quality figures");
  if (r->par->rank == 0 || !whole) /* (one file: rank 0 has the whole mesh; pieces: each its own) */
    AGREE(r, i2m_quality_compute(r->mesh, r->img, p->ratio, p->facet_angle, &r->quality));
  else
    AGREE(r, I2M_OK);
  if (!whole) i2m_dist_reduce_quality(r->par, &r->quality);
  phase_end(r, I2M_PHASE_QUALITY);
  if (r->par->rank == 0) { /* (on stderr even with --quiet, as warn_split_components) */
    const i2m_write_opts_t wo = write_opts(r); /* (the tissue names the writers get) */
    i2m_report_warn_labels(stderr, &r->quality, r->img, wo.names, I2M_VOLUME_WARN_FRACTION);
  }
  rep->input = r->opt.input;
  rep->output = r->opt.output;
  rep->img = r->img;
  rep->params = p;
  i2m_refine_get_stats(r->ref, &rep->stats);
  if (r->distributed) i2m_dist_sum_stats(r->par, &rep->stats);
  int64_t counts[3] = {r->mesh->nv, r->mesh->nt, r->mesh->ntri};
  if (!whole) i2m_par_sum_i64(r->par, counts, 3); /* (vertices shared by pieces counted in each) */
  rep->nv = counts[0];
  rep->nt = counts[1];
  rep->ntri = counts[2];
  rep->total_seconds = i2m_wtime() - r->t0;
  rep->peak_rss = i2m_peak_rss_bytes();
  rep->threads = r->team.threads;
  rep->ranks = r->par->size;
  rep->team = &r->team;
  rep->dist = r->distributed ? &r->dist : NULL;
  rep->quality = &r->quality;
  rep->pieces = r->pieces;
  rep->whole_min_voxels = I2M_WHOLE_MIN_VOXELS;
  if (r->par->rank != 0) return I2M_OK;
  if (!r->opt.quiet) i2m_report_print(stdout, rep);
  if (r->opt.report) I2M_CALL(i2m_report_write_json(r->opt.report, rep));
  return I2M_OK;
}

static void run_free(run_t *r)
{
  i2m_quality_free(&r->quality);
  i2m_threads_report_free(&r->team);
  i2m_dist_report_free(&r->dist);
  i2m_free(&r->pieces);
  i2m_tetmesh_destroy(&r->mesh);
  i2m_refine_destroy(&r->ref);
  i2m_edt_destroy(&r->edt);
  i2m_image_destroy(&r->img);
}

/* One error line, on rank 0 (the message says which rank failed). */
static int fail(const i2m_par_t *par, int code)
{
  if (par->rank == 0) fprintf(stderr, "i2m: %s\n", i2m_error_message());
  return code;
}

int main(int argc, char **argv)
{
  i2m_malloc_tune();
  i2m_par_t par;
  if (i2m_par_init(&argc, &argv, &par) != I2M_OK) {
    fprintf(stderr, "i2m: %s\n", i2m_error_message());
    return 2;
  }
  i2m_outfile_signals(); /* (after MPI's initialisation, which may set handlers of its own) */
  run_t r;
  memset(&r, 0, sizeof r);
  r.par = &par;
  r.distributed = par.mpi;
  r.t0 = i2m_wtime();
  int code = 0;
  if (i2m_par_agree(&par, cli_parse(argc, argv, &r.opt)) != I2M_OK) { /* (a bad option on one rank stops all) */
    code = fail(&par, 2);
  } else if (r.opt.help || r.opt.version) {
    if (par.rank == 0 && r.opt.help) cli_usage(stdout);
    if (par.rank == 0 && r.opt.version) printf("i2m 0.1\n");
  } else {
    /* rank 0 shows progress and the summary; the others only warnings, with their rank */
    const i2m_log_level_t level = r.opt.quiet ? I2M_LOG_QUIET : r.opt.verbose ? I2M_LOG_DEBUG : I2M_LOG_INFO;
    i2m_log_set_level(par.rank == 0 || level <= I2M_LOG_WARN ? level : I2M_LOG_WARN);
    i2m_log_set_prefix(par.prefix);
    if (r.opt.threads > 0) i2m_threads_limit(r.opt.threads); /* every phase, not only refinement */
    i2m_err_t err = run_mesher(&r);
    if (err == I2M_OK) err = report(&r);
    err = i2m_par_agree(&par, err);
    if (err != I2M_OK) code = fail(&par, err == I2M_ERR_ARG ? 2 : 1); /* (an option the image refutes: 2 as a bad option) */
    run_free(&r);
  }
  i2m_par_finalize(&par);
  return code;
}
