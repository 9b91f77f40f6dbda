/* cli layer: bin/i2m, the image-to-mesh driver: read, the mesher's steps (the api layer's
 * pipeline: distance transform, refinement, extraction), write, report.  The only place that
 * calls exit codes.
 *
 * Started by an MPI launcher (mpirun, mpiexec, srun), every rank reads the image and the
 * pipeline refines in parallel; the writer either writes each rank's piece (.pvtu) or stitches
 * them on rank 0.  Every step that can fail agrees on the error across the ranks, so that all
 * of them end with the same exit code and rank 0 prints the one message. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "i2m/io.h"
#include "i2m/pipeline.h"
#include "i2m/quality.h"
#include "options.h"

typedef struct {
  const i2m_par_t *par;
  cli_options_t opt;
  i2m_image_t *img;
  i2m_pipeline_t pipe;         /* the mesher's steps and what they made */
  i2m_quality_t quality;
  i2m_report_t rep;
  double t0;
} run_t;

/* Does each rank write its own piece (-o NAME.pvtu), rather than rank 0 one stitched file? */
static bool writes_pieces(const cli_options_t *o) { return i2m_format_from_path(o->output) == I2M_FORMAT_PVTU; }

/* The pipeline's options from the command line's. */
static i2m_pipeline_opts_t pipeline_opts(const cli_options_t *o)
{
  return (i2m_pipeline_opts_t){.params = o->params,
                               .threads = o->threads,
                               .depth = o->depth,
                               .coarse_factor = o->coarse_factor,
                               .sliver_angle = o->sliver_angle,
                               .max_memory = o->max_memory,
                               .pin = !o->no_pin,
                               .deterministic = o->deterministic != 0,
                               .check = o->check != 0,
                               .checksum = o->report != NULL, /* (only the JSON report gives it) */
                               .trace = o->trace,
                               .spread_output = writes_pieces(o)};
}

/* How the mesh is written: the writers' defaults, changed by the options; the image's tissue
 * names (kept when its voxels are released; every rank read the image, so every rank has
 * them). */
static i2m_write_opts_t write_opts(const run_t *r)
{
  i2m_write_opts_t wo = i2m_write_opts_default();
  wo.names = r->img->names;
  if (r->opt.msh_version) wo.msh_version = r->opt.msh_version;
  if (r->opt.ascii) wo.ascii = true;
  wo.compress = !r->opt.vtu_raw;
  return wo;
}

/* Every large image component the mesh splits, on stderr (even with --quiet: the mesh is
 * then not what the user expects of it). */
static void warn_split_components(const run_t *r)
{
  i2m_refine_stats_t st;
  i2m_refine_get_stats(r->pipe.ref, &st);
  for (int l = 1; l < r->img->nlabels; l++) {
    const i2m_label_pieces_t *p = &r->pipe.pieces[l];
    if (p->split_components) /* (the rule's rounds and points say why: none placed, or rounds out) */
      fprintf(stderr,
              "i2m: warning: label %lld: %lld of its %lld image components of >= %d voxels come out in several pieces "
              "(the component rule ran %lld of at most %d rounds, %lld bridge vertices%s)\n",
              (long long)p->value, (long long)p->split_components, (long long)p->large_components, I2M_WHOLE_MIN_VOXELS,
              (long long)st.bridge_rounds, I2M_BRIDGE_ROUNDS, (long long)st.bridges, r->par->size > 1 ? " on rank 0" : "");
  }
}

/* For a phase rank 0 runs alone (the stitched file, the figures of the whole mesh): its threads
 * take the cores of the node's other ranks, which wait asleep meanwhile.  Returns the count to
 * restore (0: nothing changed). */
static int borrow_node_cores(const run_t *r)
{
  if (r->par->size == 1 || r->par->rank != 0) return 0;
  const int T = r->opt.threads > 0 ? r->opt.threads : i2m_threads_default();
  return i2m_threads_set(i2m_par_node_threads(r->par, T));
}

static void give_back_cores(int was)
{
  if (was > 0) i2m_threads_set(was);
}

/* The same step on every rank, its error agreed on. */
#define AGREE(r, call) I2M_CALL(i2m_par_agree((r)->par, (call)))

static i2m_err_t run_mesher(run_t *r)
{
  cli_options_t *o = &r->opt;
  i2m_pipeline_t *p = &r->pipe;
  p->par = r->par;
  p->distributed = r->par->mpi;
  p->opt = pipeline_opts(o);
  i2m_pipeline_phase_begin(p, "reading the image");
  i2m_image_read_opts_t ro = {.allow_external_data = o->allow_external_data != 0, .header_only = true};
  AGREE(r, i2m_image_read_with(o->input, &ro, &r->img, NULL)); /* (the options checked before the voxels are read) */
  AGREE(r, i2m_refine_params_check_geometry(&o->params, r->img));
  i2m_image_destroy(&r->img);
  ro.header_only = false;
  I2M_CALL(i2m_dist_image_read(r->par, o->input, &ro, &r->img)); /* (rank 0 reads, the others receive) */
  AGREE(r, i2m_refine_params_check(&o->params, r->img));
  AGREE(r, i2m_pipeline_check_estimate(r->par, r->img, &p->opt));
  i2m_pipeline_phase_end(p, I2M_PHASE_READ);

  p->img = r->img;
  I2M_CALL(i2m_pipeline_mesh(p)); /* (agreed on inside) */
  if (r->par->rank == 0) warn_split_components(r);

  i2m_pipeline_phase_begin(p, "writing the mesh");
  const i2m_write_opts_t wo = write_opts(r);
  const int was = writes_pieces(o) ? 0 : borrow_node_cores(r);
  const i2m_err_t err = i2m_mesh_write_par(r->par, &p->mesh, o->output, &wo); /* (agreed on inside) */
  give_back_cores(was);
  I2M_CALL(err);
  i2m_pipeline_phase_end(p, I2M_PHASE_WRITE);
  return I2M_OK;
}

static i2m_err_t report(run_t *r)
{
  i2m_report_t *rep = &r->rep;
  i2m_pipeline_t *pipe = &r->pipe;
  const i2m_refine_params_t *p = i2m_refine_params(pipe->ref);
  const bool whole = r->par->size == 1 || !writes_pieces(&r->opt);
  i2m_pipeline_phase_begin(pipe, "quality figures");
  const int was = whole ? borrow_node_cores(r) : 0;
  i2m_err_t err = I2M_OK;
  if (r->par->rank == 0 || !whole) /* (one file: rank 0 has the whole mesh; pieces: each its own) */
    err = i2m_quality_compute(pipe->mesh, r->img, p->ratio, p->facet_angle, &r->quality);
  give_back_cores(was);
  AGREE(r, err);
  if (!whole) i2m_dist_reduce_quality(r->par, &r->quality);
  i2m_pipeline_phase_end(pipe, I2M_PHASE_QUALITY);
  memcpy(rep->phase_seconds, pipe->phase_seconds, sizeof rep->phase_seconds);
  rep->checksum = pipe->checksum;
  rep->working_tets = pipe->working_tets;
  rep->sliver_angle = r->opt.sliver_angle;
  rep->slivers = pipe->slivers;
  rep->bands_before = pipe->bands_before;
  if (r->par->rank == 0) { /* (on stderr even with --quiet, as warn_split_components) */
    const i2m_write_opts_t wo = write_opts(r); /* (the tissue names the writers get) */
    i2m_report_warn_labels(stderr, &r->quality, r->img, wo.names, I2M_VOLUME_WARN_FRACTION);
  }
  rep->input = r->opt.input;
  rep->output = r->opt.output;
  rep->img = r->img;
  rep->params = p;
  i2m_refine_get_stats(pipe->ref, &rep->stats);
  if (pipe->distributed) i2m_dist_sum_stats(r->par, &rep->stats);
  int64_t counts[3] = {pipe->mesh->nv, pipe->mesh->nt, pipe->mesh->ntri};
  if (!whole) i2m_par_sum_i64(r->par, counts, 3); /* (vertices shared by pieces counted in each) */
  rep->nv = counts[0];
  rep->nt = counts[1];
  rep->ntri = counts[2];
  rep->total_seconds = i2m_wtime() - r->t0;
  rep->peak_rss = i2m_peak_rss_bytes();
  rep->threads = pipe->team.threads;
  rep->ranks = r->par->size;
  rep->team = &pipe->team;
  rep->dist = pipe->distributed ? &pipe->dist : NULL;
  rep->quality = &r->quality;
  rep->pieces = pipe->pieces;
  rep->whole_min_voxels = I2M_WHOLE_MIN_VOXELS;
  if (r->par->rank != 0) return I2M_OK;
  if (!r->opt.quiet) i2m_report_print(stdout, rep);
  if (r->opt.report) I2M_CALL(i2m_report_write_json(r->opt.report, rep));
  return I2M_OK;
}

static void run_free(run_t *r)
{
  i2m_quality_free(&r->quality);
  i2m_pipeline_free(&r->pipe);
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
