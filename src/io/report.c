/* io layer: the run report (stdout summary and JSON file). */
#include "i2m/report.h"

#include <errno.h>
#include <math.h>
#include <string.h>

const char *i2m_phase_name(int phase)
{
  static const char *names[I2M_NPHASES] = {"read",       "distance_transform", "refinement", "slivers",
                                           "extraction", "write",              "quality"};
  return phase >= 0 && phase < I2M_NPHASES ? names[phase] : "?";
}

/* Large image components over all labels, and those the mesh splits. */
static void pieces_totals(const i2m_report_t *r, int64_t *large, int64_t *split)
{
  *large = *split = 0;
  for (int l = 1; r->pieces && r->img && l < r->img->nlabels; l++) {
    *large += r->pieces[l].large_components;
    *split += r->pieces[l].split_components;
  }
}

static double tets_per_second(const i2m_report_t *r)
{
  double t = r->phase_seconds[I2M_PHASE_REFINE];
  return t > 0 ? (double)r->nt / t : 0;
}

/* "below 5/10/15/20 deg: a/b/c/d, above 160/170 deg: e/f" */
static void text_bands(FILE *f, const i2m_dihedral_bands_t *b)
{
  fprintf(f, "tets with a dihedral angle below ");
  for (int k = 0; k < I2M_DIHEDRAL_NLOW; k++) fprintf(f, "%s%g", k ? "/" : "", i2m_dihedral_low_degrees(k));
  fprintf(f, " deg: ");
  for (int k = 0; k < I2M_DIHEDRAL_NLOW; k++) fprintf(f, "%s%lld", k ? "/" : "", (long long)b->below[k]);
  fprintf(f, ", above ");
  for (int k = 0; k < I2M_DIHEDRAL_NHIGH; k++) fprintf(f, "%s%g", k ? "/" : "", i2m_dihedral_high_degrees(k));
  fprintf(f, " deg: ");
  for (int k = 0; k < I2M_DIHEDRAL_NHIGH; k++) fprintf(f, "%s%lld", k ? "/" : "", (long long)b->above[k]);
}

/* {"below_5": a, ..., "above_170": f} */
static void json_bands(FILE *f, const i2m_dihedral_bands_t *b)
{
  fprintf(f, "{");
  for (int k = 0; k < I2M_DIHEDRAL_NLOW; k++) fprintf(f, "\"below_%g\": %lld, ", i2m_dihedral_low_degrees(k), (long long)b->below[k]);
  for (int k = 0; k < I2M_DIHEDRAL_NHIGH; k++)
    fprintf(f, "\"above_%g\": %lld%s", i2m_dihedral_high_degrees(k), (long long)b->above[k], k + 1 < I2M_DIHEDRAL_NHIGH ? ", " : "}");
}

void i2m_report_print(FILE *f, const i2m_report_t *r)
{
  const i2m_quality_t *q = r->quality;
  fprintf(f, "i2m: %s -> %s\n", r->input, r->output);
  fprintf(f, "  parameters   delta %.4g mm, ratio %.3g, facet angle %.3g deg, size %.4g mm\n", r->params->delta,
          r->params->ratio, r->params->facet_angle, r->params->size);
  fprintf(f, "  mesh         %lld vertices, %lld tetrahedra, %lld interface triangles\n", (long long)r->nv,
          (long long)r->nt, (long long)r->ntri);
  fprintf(f, "  refinement   %lld insertions (R1 %lld, R2 %lld, R3 %lld, R4 %lld, R5 %lld, R6 %lld, R8 %lld), %lld removals (R7)\n",
          (long long)r->stats.insertions, (long long)r->stats.rule[1], (long long)r->stats.rule[2],
          (long long)r->stats.rule[3], (long long)r->stats.rule[4], (long long)r->stats.rule[5],
          (long long)r->stats.rule[6], (long long)r->stats.bridges, (long long)r->stats.removals);
  if (r->stats.fragments)
    fprintf(f, "  fragments    %lld fragments (%lld tets) given a neighbour's label\n", (long long)r->stats.fragments,
            (long long)r->stats.fragment_tets);
  if (r->pieces) {
    int64_t large, split;
    pieces_totals(r, &large, &split);
    fprintf(f, "  components   %lld image components of >= %lld voxels, %lld of them split in the mesh\n", (long long)large,
            (long long)r->whole_min_voxels, (long long)split);
  }
  if (r->sliver_angle > 0) {
    const i2m_sliver_stats_t *v = &r->slivers;
    fprintf(f, "  slivers      %lld -> %lld tets with a dihedral angle below %.3g deg (smallest %.3g -> %.3g deg); %lld of %lld changes kept (%lld points inserted, %lld vertices removed, the others vertex moves)\n",
            (long long)v->slivers_before, (long long)v->slivers_after, r->sliver_angle, v->min_before, v->min_after,
            (long long)v->kept, (long long)v->tried, (long long)v->inserted, (long long)v->removed);
  }
  fprintf(f, "  time         ");
  for (int p = 0; p < I2M_NPHASES; p++) fprintf(f, "%s %.2f s, ", i2m_phase_name(p), r->phase_seconds[p]);
  fprintf(f, "total %.2f s\n", r->total_seconds);
  fprintf(f, "  speed        %.3g tets/s (refinement), %d thread(s), %d rank(s)\n", tets_per_second(r), r->threads,
          r->ranks);
  if (r->team && r->team->threads > 1) {
    const i2m_threads_report_t *t = r->team;
    fprintf(f, "  threads      %s; %lld capacity pauses\n", t->binding, (long long)t->pauses);
    for (int k = 0; k < t->threads; k++) {
      const i2m_thread_figures_t *g = &t->thread[k];
      fprintf(f, "    thread %-3d core %-3d %9lld insertions %7lld removals %8lld rollbacks %6lld waits, idle %.2f s\n", k,
              g->core, (long long)g->insertions, (long long)g->removals, (long long)g->rollbacks, (long long)g->waits,
              g->idle_seconds);
    }
  }
  if (r->dist) {
    const i2m_dist_report_t *d = r->dist;
    fprintf(f, "  ranks        %d, octree depth %d (%d subregions)%s: %lld tasks (%lld wide), %lld submeshes moved, %.3g MB (%.3g bytes per output tet), %.2f s\n",
            d->ranks, d->depth, 1 << (3 * d->depth), d->deterministic ? ", deterministic" : "", (long long)d->tasks,
            (long long)d->wide_tasks, (long long)d->tiles_moved, (double)d->bytes / 1048576.0,
            r->nt ? (double)d->bytes / (double)r->nt : 0.0, d->fine_seconds);
    for (int k = 0; k < d->ranks; k++) {
      const i2m_rank_figures_t *g = &d->rank[k];
      fprintf(f, "    rank %-4d  preprocess %.2f s, meshing %.2f s, communication %.2f s, idle %.2f s; %lld tasks (%lld on part of their block), %lld insertions, %lld tets, %lld submeshes in, %lld out (%lld while refining), peak %.0f MB\n",
              k, g->preprocess, g->meshing, g->comm, g->idle, (long long)g->tasks, (long long)g->skipping_tasks, (long long)g->insertions, (long long)g->tets,
              (long long)g->tiles_in, (long long)g->tiles_out, (long long)g->answered_while_refining, g->peak_rss / 1048576.0);
    }
    if (d->balance_calls)
      fprintf(f, "    balance    %lld cells moved after the tasks, %.3g MB, %.2f s: the most output tets on a rank %.2f -> %.2f times the mean\n",
              (long long)d->balance_cells, (double)d->balance_bytes / 1048576.0, d->balance_seconds, d->balance_before,
              d->balance_after);
    else if (d->ranks > 1)
      fprintf(f, "    balance    none: one file, stitched on rank 0 (pieces, -o NAME.pvtu, are spread evenly)\n");
  }
  fprintf(f, "  memory       peak %.1f MB, %.0f bytes per output tet\n", (double)r->peak_rss / 1048576.0,
          r->nt ? (double)r->peak_rss / (double)r->nt : 0.0);
  if (q) {
    fprintf(f, "  quality      dihedral %.2f..%.2f deg, max radius-edge %.3f (%lld above %.3g), min facet angle %.2f deg\n",
            q->min_dihedral, q->max_dihedral, q->max_radius_edge, (long long)q->n_ratio_above, q->ratio_bound,
            q->min_facet_angle);
    fprintf(f, "               %lld interface triangles below %.3g deg (%lld of them at junctions of 3+ labels)\n",
            (long long)q->n_facet_below, q->facet_bound, (long long)q->n_facet_below_junction);
    fprintf(f, "               ");
    text_bands(f, &q->bands);
    if (r->sliver_angle > 0) {
      fprintf(f, "\n               (before the sliver pass: ");
      text_bands(f, &r->bands_before);
      fprintf(f, ")");
    }
    fprintf(f, "\n");
  }
}

/* ---- JSON ---- */


static void json_vec3(FILE *f, const double x[3])
{
  for (int a = 0; a < 3; a++) {
    fputs(a ? ", " : "[", f);
    i2m_json_number(f, x[a]);
  }
  fputc(']', f);
}

static void json_params(FILE *f, const i2m_report_t *r)
{
  const i2m_refine_params_t *p = r->params;
  fprintf(f, "  \"parameters\": {\"delta\": ");
  i2m_json_number(f, p->delta);
  fprintf(f, ", \"ratio\": ");
  i2m_json_number(f, p->ratio);
  fprintf(f, ", \"facet_angle\": ");
  i2m_json_number(f, p->facet_angle);
  fprintf(f, ", \"size\": ");
  i2m_json_number(f, p->size);
  fprintf(f, ", \"size_labels\": [");
  for (int k = 0; k < p->nlabel_sizes; k++) {
    fprintf(f, "%s{\"label\": %lld, \"size\": ", k ? ", " : "", (long long)p->label_sizes[k].value);
    i2m_json_number(f, p->label_sizes[k].size);
    fprintf(f, "}");
  }
  fprintf(f, "], \"regions\": [");
  for (int k = 0; k < p->nregions; k++) {
    const i2m_region_t *g = &p->regions[k];
    fprintf(f, "%s{\"lo\": ", k ? ", " : "");
    json_vec3(f, g->lo);
    fprintf(f, ", \"hi\": ");
    json_vec3(f, g->hi);
    fprintf(f, ", \"size\": ");
    i2m_json_number(f, g->size);
    fprintf(f, ", \"ratio\": ");
    i2m_json_number(f, g->ratio);
    fprintf(f, "}");
  }
  fprintf(f, "], \"threads\": %d, \"ranks\": %d},\n", r->threads, r->ranks);
}

/* The label's census, by original value (NULL when there is none). */
static const i2m_label_pieces_t *pieces_of(const i2m_report_t *r, int64_t value)
{
  if (!r->pieces || !r->img) return NULL;
  for (int l = 0; l < r->img->nlabels; l++)
    if (r->pieces[l].value == value) return &r->pieces[l];
  return NULL;
}

static void json_quality(FILE *f, const i2m_report_t *r)
{
  const i2m_quality_t *q = r->quality;
  fprintf(f, "  \"quality\": {");
  i2m_json_member(f, "min_dihedral", q->min_dihedral, false);
  i2m_json_member(f, "max_dihedral", q->max_dihedral, false);
  i2m_json_member(f, "max_radius_edge", q->max_radius_edge, false);
  fprintf(f, "\"tets_above_ratio\": %lld, ", (long long)q->n_ratio_above);
  i2m_json_member(f, "min_facet_angle", q->min_facet_angle, false);
  fprintf(f, "\"facets_below_angle\": %lld, ", (long long)q->n_facet_below);
  fprintf(f, "\"facets_below_angle_at_junctions\": %lld, \"dihedral_bands\": ", (long long)q->n_facet_below_junction);
  json_bands(f, &q->bands);
  fprintf(f, ", \"dihedral_histogram\": [");
  for (int k = 0; k < 180; k++) fprintf(f, "%s%lld", k ? ", " : "", (long long)q->dihedral_hist[k]);
  fprintf(f, "]},\n  \"labels\": [");
  for (int l = 0; l < q->nlabels; l++) {
    const i2m_label_figures_t *g = &q->labels[l];
    double err = g->voxel_volume > 0 ? 100.0 * (g->volume - g->voxel_volume) / g->voxel_volume : 0;
    fprintf(f, "%s\n    {\"label\": %lld, \"tets\": %lld, \"volume_mm3\": %.8g, \"voxel_volume_mm3\": %.8g, \"volume_error_percent\": %.4g",
            l ? "," : "", (long long)g->value, (long long)g->ntets, g->volume, g->voxel_volume, err);
    const i2m_label_pieces_t *p = pieces_of(r, g->value);
    if (p)
      fprintf(f, ", \"image_components\": %lld, \"large_components\": %lld, \"mesh_pieces\": %lld, \"split_components\": %lld",
              (long long)p->image_components, (long long)p->large_components, (long long)p->mesh_pieces,
              (long long)p->split_components);
    fprintf(f, "}");
  }
  fprintf(f, "\n  ],\n");
}

/* The voxel count of a label value (0 when the image has none). */
static int64_t voxels_of(const i2m_image_t *img, int64_t value)
{
  for (int l = 0; img && l < img->nlabels; l++)
    if (img->label_value[l] == value) return img->label_count[l];
  return 0;
}

/* " (name)" with control characters replaced, or "" without a name: one line whatever the
 * colour table holds. */
static void name_suffix(const i2m_label_names_t *names, int64_t value, char *out, size_t cap)
{
  const char *s = i2m_label_name(names, value);
  out[0] = '\0';
  if (!s || cap < 4) return;
  size_t k = 0;
  out[k++] = ' ';
  out[k++] = '(';
  for (; *s && k + 2 < cap; s++) out[k++] = (unsigned char)*s < 32 || *s == 127 ? '?' : *s;
  out[k++] = ')';
  out[k] = '\0';
}

int i2m_report_warn_labels(FILE *f, const i2m_quality_t *q, const i2m_image_t *img, const i2m_label_names_t *names,
                           double tolerance)
{
  int lines = 0;
  for (int l = 0; q && l < q->nlabels; l++) {
    const i2m_label_figures_t *g = &q->labels[l];
    if (!(g->voxel_volume > 0)) continue;
    const double rel = (g->volume - g->voxel_volume) / g->voxel_volume;
    if (g->ntets > 0 && fabs(rel) <= tolerance) continue;
    char name[128];
    name_suffix(names, g->value, name, sizeof name);
    const long long vox = (long long)voxels_of(img, g->value);
    if (g->ntets == 0)
      fprintf(f, "i2m: warning: label %lld%s: absent from the mesh (%lld voxels, %.4g mm3 in the image)\n",
              (long long)g->value, name, vox, g->voxel_volume);
    else
      fprintf(f, "i2m: warning: label %lld%s: mesh volume %.4g mm3 is %+.1f%% off its voxel volume %.4g mm3 (%lld voxels)\n",
              (long long)g->value, name, g->volume, 100 * rel, g->voxel_volume, vox);
    lines++;
  }
  return lines;
}

/* The distributed run: totals and every rank's figures (the paper's Fig. 7 breakdown). */
static void json_dist(FILE *f, const i2m_report_t *r)
{
  const i2m_dist_report_t *d = r->dist;
  fprintf(f, "  \"dist\": {\"ranks\": %d, \"depth\": %d, \"subregions\": %d, \"deterministic\": %s, \"tasks\": %lld, "
             "\"wide_tasks\": %lld, \"submeshes_moved\": %lld, \"bytes\": %lld, \"bytes_per_tet\": %.2f, \"fine_seconds\": %.4f, "
             "\"balance\": {\"cells\": %lld, \"bytes\": %lld, \"seconds\": %.4f, \"most_before\": %.4f, \"most_after\": %.4f}, "
             "\"per_rank\": [",
          d->ranks, d->depth, 1 << (3 * d->depth), d->deterministic ? "true" : "false", (long long)d->tasks,
          (long long)d->wide_tasks, (long long)d->tiles_moved, (long long)d->bytes, r->nt ? (double)d->bytes / (double)r->nt : 0.0,
          d->fine_seconds, (long long)d->balance_cells, (long long)d->balance_bytes, d->balance_seconds, d->balance_before,
          d->balance_after);
  for (int k = 0; k < d->ranks; k++) {
    const i2m_rank_figures_t *g = &d->rank[k];
    fprintf(f, "%s\n    {\"rank\": %d, \"preprocess_seconds\": %.4f, \"meshing_seconds\": %.4f, \"comm_seconds\": %.4f, "
               "\"idle_seconds\": %.4f, \"comm_parts_seconds\": {\"wait_data\": %.4f, \"pack\": %.4f, \"unpack\": %.4f, "
               "\"drop\": %.4f, \"merge\": %.4f}, \"tasks\": %lld, \"wide_tasks\": %lld, \"skipping_tasks\": %lld, \"submeshes_in\": %lld, \"submeshes_out\": %lld, "
               "\"bytes_in\": %lld, \"bytes_out\": %lld, \"answered_while_refining\": %lld, \"insertions\": %lld, "
               "\"removals\": %lld, \"tets\": %lld, \"peak_tets\": %lld, \"peak_rss_bytes\": %.0f}",
            k ? "," : "", k, g->preprocess, g->meshing, g->comm, g->idle, g->wait_data, g->pack, g->unpack, g->drop, g->merge,
            (long long)g->tasks, (long long)g->wide_tasks, (long long)g->skipping_tasks,
            (long long)g->tiles_in, (long long)g->tiles_out, (long long)g->bytes_in, (long long)g->bytes_out,
            (long long)g->answered_while_refining, (long long)g->insertions, (long long)g->removals, (long long)g->tets,
            (long long)g->peak_tets, g->peak_rss);
  }
  fprintf(f, "]},\n");
}

i2m_err_t i2m_report_write_json(const char *path, const i2m_report_t *r)
{
  i2m_outfile_t out;
  I2M_CALL(i2m_outfile_open(&out, path, "w"));
  FILE *f = out.f;
  fprintf(f, "{\n  \"input\": ");
  i2m_json_string(f, r->input);
  fprintf(f, ",\n  \"output\": ");
  i2m_json_string(f, r->output);
  fprintf(f, ",\n");
  json_params(f, r);
  fprintf(f, "  \"counts\": {\"vertices\": %lld, \"tetrahedra\": %lld, \"interface_triangles\": %lld, \"working_tetrahedra\": %lld, \"checksum\": \"%016llx\"},\n",
          (long long)r->nv, (long long)r->nt, (long long)r->ntri, (long long)r->working_tets, (unsigned long long)r->checksum);
  const i2m_refine_stats_t *s = &r->stats;
  fprintf(f, "  \"refinement\": {\"insertions\": %lld, \"removals\": %lld, \"rollbacks\": %lld, \"failed\": %lld, \"duplicates\": %lld, \"tets_created\": %lld, ",
          (long long)s->insertions, (long long)s->removals, (long long)s->rollbacks, (long long)s->failed,
          (long long)s->duplicates, (long long)s->tets_created);
  fprintf(f, "\"fragments\": %lld, \"fragment_tets\": %lld, \"bridges\": %lld, \"bridge_rounds\": %lld, ",
          (long long)s->fragments, (long long)s->fragment_tets, (long long)s->bridges, (long long)s->bridge_rounds);
  if (r->pieces) {
    int64_t large, split;
    pieces_totals(r, &large, &split);
    fprintf(f, "\"components\": {\"min_voxels\": %lld, \"large\": %lld, \"split\": %lld}, ", (long long)r->whole_min_voxels,
            (long long)large, (long long)split);
  }
  fprintf(f, "\"rules\": {\"R1\": %lld, \"R2\": %lld, \"R3\": %lld, \"R4\": %lld, \"R5\": %lld, \"R6\": %lld, \"R7\": %lld, \"R8\": %lld}},\n",
          (long long)s->rule[1], (long long)s->rule[2], (long long)s->rule[3], (long long)s->rule[4],
          (long long)s->rule[5], (long long)s->rule[6], (long long)s->rule[7], (long long)s->bridges);
  if (r->sliver_angle > 0) {
    const i2m_sliver_stats_t *v = &r->slivers;
    fprintf(f, "  \"slivers\": {\"angle\": %.6g, \"before\": %lld, \"after\": %lld, ", r->sliver_angle,
            (long long)v->slivers_before, (long long)v->slivers_after);
    i2m_json_member(f, "min_dihedral_before", v->min_before, false);
    i2m_json_member(f, "min_dihedral_after", v->min_after, false);
    fprintf(f, "\"moves_tried\": %lld, \"moves_kept\": %lld, \"points_inserted\": %lld, \"vertices_removed\": %lld, \"dihedral_bands_before\": ",
            (long long)v->tried, (long long)v->kept, (long long)v->inserted, (long long)v->removed);
    json_bands(f, &r->bands_before);
    fprintf(f, "},\n");
  }
  fprintf(f, "  \"time_seconds\": {");
  for (int p = 0; p < I2M_NPHASES; p++) fprintf(f, "\"%s\": %.4f, ", i2m_phase_name(p), r->phase_seconds[p]);
  fprintf(f, "\"total\": %.4f},\n", r->total_seconds);
  fprintf(f, "  \"speed\": {\"tets_per_second\": %.6g, \"tets_per_second_total\": %.6g},\n", tets_per_second(r),
          r->total_seconds > 0 ? (double)r->nt / r->total_seconds : 0);
  fprintf(f, "  \"memory\": {\"peak_rss_bytes\": %zu, \"bytes_per_tet\": %.2f},\n", r->peak_rss,
          r->nt ? (double)r->peak_rss / (double)r->nt : 0.0);
  if (r->team) {
    const i2m_threads_report_t *t = r->team;
    fprintf(f, "  \"threads\": {\"count\": %d, \"pinned\": %s, \"binding\": ", t->threads, t->pinned ? "true" : "false");
    i2m_json_string(f, t->binding);
    fprintf(f, ", \"capacity_pauses\": %lld, \"coarse_seconds\": %.4f, \"fine_seconds\": %.4f, ", (long long)t->pauses,
            t->coarse_seconds, t->fine_seconds);
    fprintf(f, "\"deterministic\": %s, \"depth\": %d, \"tile_mm\": %.4g, \"phases\": %lld, \"rounds\": %lld, \"sequential_ops\": %lld, ",
            t->deterministic ? "true" : "false", t->depth, t->tile_side, (long long)t->phases, (long long)t->rounds,
            (long long)t->sequential_ops);
    fprintf(f, "\"deferred\": %lld, \"per_thread\": [", (long long)r->stats.deferred);
    for (int k = 0; k < t->threads; k++) {
      const i2m_thread_figures_t *g = &t->thread[k];
      fprintf(f, "%s\n    {\"thread\": %d, \"core\": %d, \"insertions\": %lld, \"removals\": %lld, \"rollbacks\": %lld, "
                 "\"contention_waits\": %lld, \"handoffs\": %lld, \"elements_given\": %lld, \"busy_seconds\": %.4f, "
                 "\"idle_seconds\": %.4f, \"wait_seconds\": %.4f}",
              k ? "," : "", k, g->core, (long long)g->insertions, (long long)g->removals, (long long)g->rollbacks,
              (long long)g->waits, (long long)g->handoffs, (long long)g->given, g->busy_seconds, g->idle_seconds,
              g->wait_seconds);
    }
    fprintf(f, "]},\n");
  }
  if (r->dist) json_dist(f, r);
  if (r->quality) json_quality(f, r);
  fprintf(f, "  \"version\": \"i2m 0.1\"\n}\n");
  return i2m_outfile_commit(&out);
}
