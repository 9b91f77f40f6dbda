/* cli layer: bin/i2m, the image-to-mesh driver: read, distance transform, refinement,
 * extraction, write, report.  The only place that calls exit codes. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "i2m/edt.h"
#include "i2m/io.h"
#include "i2m/quality.h"
#include "i2m/refine.h"
#include "i2m/report.h"
#include "i2m/threads.h"
#include "options.h"

typedef struct {
  cli_options_t opt;
  i2m_image_t *img;
  i2m_edt_t *edt;
  i2m_refine_t *ref;
  i2m_tetmesh_t *mesh;
  i2m_label_pieces_t *pieces; /* per label: image components and mesh pieces */
  i2m_quality_t quality;
  i2m_threads_report_t team;
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

static i2m_err_t run_mesher(run_t *r)
{
  cli_options_t *o = &r->opt;
  phase_begin(r, "reading the image");
  I2M_CALL(i2m_image_read(o->input, &r->img));
  I2M_CALL(i2m_refine_params_check(&o->params, r->img));
  phase_end(r, I2M_PHASE_READ);

  phase_begin(r, "distance transform");
  I2M_CALL(i2m_edt_create(r->img, &r->edt));
  if (r->edt->labels_packed) i2m_image_release_voxels(r->img); /* the transform answers label queries */
  phase_end(r, I2M_PHASE_EDT);

  phase_begin(r, "refinement");
  I2M_CALL(i2m_refine_create(r->img, r->edt, &o->params, &r->ref));
  i2m_threads_opts_t to = {o->threads, o->coarse_factor, !o->no_pin, o->deterministic != 0, o->depth};
  I2M_CALL(i2m_threads_refine(r->ref, &to, &r->team));
  if (o->sliver_angle > 0) { /* (the rules it applies read the grids: before they go) */
    phase_end(r, I2M_PHASE_REFINE);
    phase_begin(r, "sliver perturbation");
    I2M_CALL(i2m_threads_perturb_slivers(r->ref, &to, o->sliver_angle, &r->rep.slivers));
    r->rep.sliver_angle = o->sliver_angle;
  }
  if (o->check) I2M_CALL(i2m_dt_check(i2m_refine_dt(r->ref), true));
  i2m_refine_release_scratch(r->ref); /* the grids' memory, before extraction adds the mesh */
  phase_end(r, o->sliver_angle > 0 ? I2M_PHASE_SLIVERS : I2M_PHASE_REFINE);

  phase_begin(r, "extraction");
  I2M_CALL(i2m_refine_repair_fragments(r->ref)); /* (asks the transform about the image) */
  I2M_CALL(i2m_refine_census(r->ref, I2M_WHOLE_MIN_VOXELS, &r->pieces));
  warn_split_components(r);
  i2m_edt_destroy(&r->edt);
  i2m_image_release_voxels(r->img);
  if (o->report) /* (only the JSON report gives it: one pass over the whole triangulation) */
    r->rep.checksum = i2m_dt_checksum(i2m_refine_dt(r->ref), &r->rep.working_tets);
  I2M_CALL(i2m_refine_extract(r->ref, &r->mesh));
  i2m_refine_release_mesh(r->ref);
  phase_end(r, I2M_PHASE_EXTRACT);
  I2M_CHECK(r->mesh->nt > 0, I2M_ERR_INPUT,
            "%s: the mesh is empty: the labelled region is smaller than what delta = %g mm can resolve; try a smaller --delta",
            o->input, i2m_refine_params(r->ref)->delta);

  phase_begin(r, "writing the mesh");
  I2M_CALL(i2m_mesh_write(r->mesh, o->output));
  phase_end(r, I2M_PHASE_WRITE);
  return I2M_OK;
}

static i2m_err_t report(run_t *r)
{
  i2m_report_t *rep = &r->rep;
  const i2m_refine_params_t *p = i2m_refine_params(r->ref);
  phase_begin(r, "quality figures");
  I2M_CALL(i2m_quality_compute(r->mesh, r->img, p->ratio, p->facet_angle, &r->quality));
  phase_end(r, I2M_PHASE_QUALITY);
  rep->input = r->opt.input;
  rep->output = r->opt.output;
  rep->img = r->img;
  rep->params = p;
  i2m_refine_get_stats(r->ref, &rep->stats);
  rep->nv = r->mesh->nv;
  rep->nt = r->mesh->nt;
  rep->ntri = r->mesh->ntri;
  rep->total_seconds = i2m_wtime() - r->t0;
  rep->peak_rss = i2m_peak_rss_bytes();
  rep->threads = r->team.threads;
  rep->ranks = 1;
  rep->team = &r->team;
  rep->quality = &r->quality;
  rep->pieces = r->pieces;
  rep->whole_min_voxels = I2M_WHOLE_MIN_VOXELS;
  if (!r->opt.quiet) i2m_report_print(stdout, rep);
  if (r->opt.report) I2M_CALL(i2m_report_write_json(r->opt.report, rep));
  return I2M_OK;
}

static void run_free(run_t *r)
{
  i2m_quality_free(&r->quality);
  i2m_free(&r->pieces);
  i2m_threads_report_free(&r->team);
  i2m_tetmesh_destroy(&r->mesh);
  i2m_refine_destroy(&r->ref);
  i2m_edt_destroy(&r->edt);
  i2m_image_destroy(&r->img);
}

/* The number of processes an MPI launcher (mpirun, mpiexec, srun with PMI) started, from
 * the variables it sets (1 when none).  The distributed level is not built yet: rather than
 * N processes each meshing the whole image into the same file, each of them stops. */
static long launched_processes(void)
{
  static const char *const vars[] = {"OMPI_COMM_WORLD_SIZE", "PMI_SIZE"};
  for (size_t k = 0; k < sizeof vars / sizeof *vars; k++) {
    const char *v = getenv(vars[k]);
    long n = v ? strtol(v, NULL, 10) : 0;
    if (n > 1) return n;
  }
  return 1;
}

int main(int argc, char **argv)
{
  run_t r;
  i2m_malloc_tune();
  memset(&r, 0, sizeof r);
  r.t0 = i2m_wtime();
  if (cli_parse(argc, argv, &r.opt) != I2M_OK) {
    fprintf(stderr, "i2m: %s\n", i2m_error_message());
    return 2;
  }
  if (r.opt.help) {
    cli_usage(stdout);
    return 0;
  }
  if (r.opt.version) {
    printf("i2m 0.1\n");
    return 0;
  }
  long nproc = launched_processes();
  if (nproc > 1) {
    fprintf(stderr,
            "i2m: started as one of %ld MPI processes, but the MPI level is not implemented yet: run one process "
            "(it uses every core of the node; see --threads)\n",
            nproc);
    return 2;
  }
  i2m_log_set_level(r.opt.quiet ? I2M_LOG_QUIET : r.opt.verbose ? I2M_LOG_DEBUG : I2M_LOG_INFO);
  if (r.opt.threads > 0) i2m_threads_limit(r.opt.threads); /* every phase, not only refinement */
  i2m_err_t err = run_mesher(&r);
  if (err == I2M_OK) err = report(&r);
  if (err != I2M_OK) fprintf(stderr, "i2m: %s\n", i2m_error_message());
  run_free(&r);
  return err == I2M_OK ? 0 : 1;
}
