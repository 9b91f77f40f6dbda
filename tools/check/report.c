/* i2m-check: the reports.  A human-readable summary, or one JSON object with every figure:
 *   { "mesh": {...}, "stitch": {...} | null (a .pvtu), "valid": bool, "validity": {...},
 *     "quality": {...} | null, "fidelity": {...} | null, "thresholds": {...}, "passed": bool,
 *     "violations": [...], "timings": {...} }
 * Non-finite numbers are written as null. */
#include "check.h"

#include <math.h>
#include <string.h>

/* ---- JSON helpers ---- */

#define JI(f, key, v, last) fprintf(f, "\"%s\": %lld%s", key, (long long)(v), (last) ? "" : ", ")
#define JB(f, key, v, last) fprintf(f, "\"%s\": %s%s", key, (v) ? "true" : "false", (last) ? "" : ", ")
#define JD(f, key, v, last) i2m_json_member(f, key, v, last)

static void json_validity(FILE *f, const ck_validity_t *v)
{
  fprintf(f, "\"validity\": {");
  JB(f, "valid", v->valid, 0);
  fprintf(f, "\"errors\": [");
  const char *p = v->errors;
  int first = 1;
  while (*p) {
    const char *q = strchr(p, ',');
    size_t n = q ? (size_t)(q - p) : strlen(p);
    fprintf(f, "%s\"%.*s\"", first ? "" : ", ", (int)n, p);
    first = 0;
    p += n + (q ? 1 : 0);
  }
  fprintf(f, "], ");
  JI(f, "index_out_of_range", v->bad_index, 0);
  JI(f, "first_index_out_of_range_tet", v->first_bad_index, 0);
  JI(f, "file_triangle_index_out_of_range", v->tri_bad_index, 0);
  JI(f, "nonfinite_vertices", v->nonfinite, 0);
  JI(f, "first_nonfinite_vertex", v->first_nonfinite, 0);
  JI(f, "inverted", v->inverted, 0);
  JI(f, "first_inverted_tet", v->first_inverted, 0);
  JI(f, "degenerate", v->degenerate, 0);
  JI(f, "first_degenerate_tet", v->first_degenerate, 0);
  JD(f, "min_volume", v->min_volume, 0);
  JI(f, "min_volume_tet", v->min_volume_tet, 0);
  JD(f, "total_volume", v->total_volume, 0);
  JI(f, "interior_faces", v->interior_faces, 0);
  JI(f, "boundary_faces", v->boundary_faces, 0);
  JI(f, "nonmanifold_faces", v->nonmanifold_faces, 0);
  JI(f, "first_nonmanifold_tet", v->first_nonmanifold_tet, 0);
  JI(f, "overlapping_faces", v->overlapping_faces, 0);
  JI(f, "first_overlapping_tet", v->first_overlapping_tet, 0);
  JI(f, "dangling_vertices", v->dangling, 0);
  JI(f, "first_dangling_vertex", v->first_dangling, 0);
  JI(f, "duplicate_vertices", v->duplicate, 0);
  JI(f, "first_duplicate_vertex", v->first_duplicate, 0);
  JI(f, "first_duplicate_of", v->first_duplicate_of, 0);
  JI(f, "boundary_edges", v->boundary_edges, 0);
  JI(f, "boundary_open_edges", v->boundary_open_edges, 0);
  JB(f, "boundary_closed", v->boundary_open_edges == 0 && !v->bad_index && !v->nonfinite, 0);
  JI(f, "interface_triangles", v->interface_triangles, 0);
  JI(f, "interface_pairs", v->interface_pairs, 0);
  JI(f, "file_triangles", v->file_triangles, 0);
  JI(f, "file_triangles_not_interface", v->file_not_interface, 0);
  JI(f, "interfaces_missing_from_file", v->interface_not_in_file, 0);
  JI(f, "file_triangle_label_mismatch", v->file_label_mismatch, 0);
  JI(f, "file_triangles_duplicate", v->file_duplicate, 0);
  JI(f, "file_triangles_outward", v->file_outward, 0);
  JI(f, "file_triangles_inward", v->file_inward, 0);
  JI(f, "file_triangles_flipped", v->file_flipped, 0);
  fprintf(f, "\"triangle_orientation\": \"%s\"", ck_validity_orientation(v));
  fprintf(f, "}");
}

static void json_quality(FILE *f, const ck_quality_t *q)
{
  fprintf(f, "\"quality\": {");
  JD(f, "min_dihedral", q->min_dihedral, 0);
  JI(f, "min_dihedral_tet", q->min_dihedral_tet, 0);
  JD(f, "max_dihedral", q->max_dihedral, 0);
  JI(f, "max_dihedral_tet", q->max_dihedral_tet, 0);
  JI(f, "tets_dihedral_below_5", q->dihedral_below[0], 0);
  JI(f, "tets_dihedral_below_10", q->dihedral_below[1], 0);
  JI(f, "tets_dihedral_below_15", q->dihedral_below[2], 0);
  JI(f, "tets_dihedral_below_20", q->dihedral_below[3], 0);
  JI(f, "tets_dihedral_above_160", q->dihedral_above[0], 0);
  JI(f, "tets_dihedral_above_170", q->dihedral_above[1], 0);
  fprintf(f, "\"dihedral_histogram\": [");
  for (int b = 0; b < CK_HIST_BINS; b++) fprintf(f, "%s%lld", b ? ", " : "", (long long)q->dihedral_hist[b]);
  fprintf(f, "], ");
  JD(f, "max_radius_edge", q->max_ratio, 0);
  JI(f, "max_radius_edge_tet", q->max_ratio_tet, 0);
  JD(f, "radius_edge_mean", q->ratio_mean, 0);
  JD(f, "radius_edge_p50", q->ratio_p50, 0);
  JD(f, "radius_edge_p90", q->ratio_p90, 0);
  JD(f, "radius_edge_p99", q->ratio_p99, 0);
  JD(f, "radius_edge_p999", q->ratio_p999, 0);
  JD(f, "radius_edge_bound", q->ratio_bound, 0);
  JI(f, "tets_above_radius_edge_bound", q->ratio_above_bound, 0);
  JI(f, "tets_above_radius_edge_2", q->ratio_above_2, 0);
  JI(f, "interface_triangles", q->ntri, 0);
  JD(f, "min_planar_angle", q->min_planar_angle, 0);
  JI(f, "min_planar_angle_triangle", q->min_planar_tri, 0);
  JD(f, "planar_angle_bound", q->facet_angle_bound, 0);
  JI(f, "triangles_below_planar_angle_bound", q->planar_below_bound, 0);
  JI(f, "triangles_below_30", q->planar_below_30, 1);
  fprintf(f, "}");
}

static void json_dist(FILE *f, const char *key, const ck_dist_t *d, double sp, int last)
{
  fprintf(f, "\"%s\": {", key);
  JD(f, "max_mm", d->max, 0);
  JD(f, "p99_mm", d->p99, 0);
  JD(f, "mean_mm", d->mean, 0);
  JD(f, "max_vox", d->max / sp, 0);
  JD(f, "p99_vox", d->p99 / sp, 0);
  JD(f, "mean_vox", d->mean / sp, 0);
  JI(f, "count", d->count, 0);
  fprintf(f, "\"where\": [");
  i2m_json_number(f, d->where[0]);
  fprintf(f, ", ");
  i2m_json_number(f, d->where[1]);
  fprintf(f, ", ");
  i2m_json_number(f, d->where[2]);
  fprintf(f, "]}%s", last ? "" : ", ");
}

static void json_fidelity(FILE *f, const ck_fidelity_t *x)
{
  double sp = x->min_spacing;
  fprintf(f, "\"fidelity\": {");
  JB(f, "distances", x->distances, 0);
  JD(f, "min_spacing", sp, 0);
  JD(f, "sample_spacing", x->sample_spacing, 0);
  JI(f, "image_interface_faces", x->image_faces, 0);
  JI(f, "mesh_samples", x->mesh_samples, 0);
  json_dist(f, "mesh_to_image", &x->mesh_to_image, sp, 0);
  json_dist(f, "image_to_mesh", &x->image_to_mesh, sp, 0);
  json_dist(f, "hausdorff", &x->two_sided, sp, 0);
  fprintf(f, "\"worst_image_face\": {\"labels\": [%lld, %lld], \"component_voxels\": [%lld, %lld], "
             "\"thinnest_run_mm\": [%.6g, %.6g]}, ",
          (long long)x->worst_pair[0], (long long)x->worst_pair[1], (long long)x->worst_component[0],
          (long long)x->worst_component[1], x->worst_thinnest[0], x->worst_thinnest[1]);
  JI(f, "missing_labels", x->missing_labels, 0);
  JI(f, "extra_labels", x->extra_labels, 0);
  JI(f, "image_components", x->image_components_total, 0);
  fprintf(f, "\"labels\": [");
  for (int i = 0; i < x->nlabels; i++) {
    const ck_label_t *L = &x->labels[i];
    fprintf(f, "%s{", i ? ", " : "");
    JI(f, "label", L->value, 0);
    JI(f, "voxels", L->voxels, 0);
    JD(f, "image_volume", L->image_volume, 0);
    JD(f, "mesh_volume", L->mesh_volume, 0);
    JD(f, "volume_error_pct", L->rel_error_pct, 0);
    JI(f, "tets", L->tets, 0);
    JI(f, "image_components", L->image_components, 0);
    JI(f, "image_components_100", L->image_components_100, 0);
    JI(f, "largest_component_voxels", L->largest_component, 0);
    JI(f, "mesh_components", L->mesh_components, 0);
    JI(f, "large_components", L->large_components, 0);
    JI(f, "split_components", L->split_components, 0);
    JB(f, "in_image", L->in_image, 0);
    JB(f, "in_mesh", L->in_mesh, 1);
    fprintf(f, "}");
  }
  fprintf(f, "]}");
}

/* The stitching errors of a .pvtu: a count, a description and the first one of each kind. */
typedef struct {
  int64_t count;
  const char *what, *first;
} stitch_error_t;

static int stitch_errors(const ck_stitch_t *st, stitch_error_t e[4])
{
  const stitch_error_t all[4] = {
      {st->coordinate_mismatches, "global ids with different coordinates in two pieces",
       st->first_mismatch},
      {st->shared_points, "points with two global ids", st->first_shared},
      {st->pieces_without_ids, "pieces without GlobalNodeId", st->first_without_ids},
      {st->one_sided_faces, "faces seen by one side only", st->first_one_sided}};
  int n = 0;
  for (int i = 0; i < 4; i++)
    if (all[i].count) e[n++] = all[i];
  return n;
}

static void json_stitch(FILE *f, const ck_stitch_t *st, const ck_mesh_t *m)
{
  stitch_error_t e[4];
  int ne = stitch_errors(st, e);
  fprintf(f, "\"stitch\": {\"pieces\": [");
  for (int p = 0; p < st->npieces; p++) {
    fprintf(f, "%s{\"path\": ", p ? ", " : "");
    i2m_json_string(f, st->piece_path[p]);
    fprintf(f, ", ");
    JI(f, "vertices", st->piece_nv[p], 0);
    JI(f, "tetrahedra", st->tet_start[p + 1] - st->tet_start[p], 0);
    JB(f, "global_ids", st->piece_has_gid[p], 1);
    fprintf(f, "}");
  }
  fprintf(f, "], ");
  JI(f, "vertices_before", st->vertices_before, 0);
  JI(f, "vertices_after", m->nv, 0);
  JI(f, "seam_vertices", st->seam_vertices, 0);
  JI(f, "coordinate_mismatches", st->coordinate_mismatches, 0);
  JI(f, "shared_points", st->shared_points, 0);
  JI(f, "pieces_without_ids", st->pieces_without_ids, 0);
  JB(f, "seams_checked", st->seams_checked, 0);
  JI(f, "seam_boundary_faces", st->seam_boundary_faces, 0);
  JI(f, "one_sided_faces", st->one_sided_faces, 0);
  fprintf(f, "\"errors\": [");
  for (int i = 0; i < ne; i++) {
    fprintf(f, "%s", i ? ", " : "");
    i2m_json_string(f, e[i].first);
  }
  fprintf(f, "]}");
}

void ck_report_json(FILE *f, const ck_result_t *r)
{
  const ck_mesh_t *m = r->mesh;
  fprintf(f, "{\"mesh\": {\"path\": ");
  i2m_json_string(f, r->mesh_path);
  fprintf(f, ", \"format\": \"%s\", ", m->format);
  JI(f, "vertices", m->nv, 0);
  JI(f, "tetrahedra", m->nt, 0);
  JI(f, "file_triangles", m->ntri, 0);
  JB(f, "file_has_triangles", m->has_tri, 0);
  JI(f, "ignored_cells", m->ignored_cells, 1);
  fprintf(f, "}, ");
  if (m->stitch)
    json_stitch(f, m->stitch, m);
  else
    fprintf(f, "\"stitch\": null");
  fprintf(f, ", \"image\": ");
  if (r->image_path)
    i2m_json_string(f, r->image_path);
  else
    fprintf(f, "null");
  fprintf(f, ", ");
  JB(f, "valid", r->validity.valid, 0);
  json_validity(f, &r->validity);
  fprintf(f, ", ");
  if (r->have_quality)
    json_quality(f, &r->quality);
  else
    fprintf(f, "\"quality\": null");
  fprintf(f, ", ");
  if (r->have_fidelity)
    json_fidelity(f, &r->fidelity);
  else
    fprintf(f, "\"fidelity\": null");
  fprintf(f, ", \"thresholds\": {");
  JD(f, "max_ratio", r->max_ratio, 0);
  JD(f, "min_facet_angle", r->min_facet_angle, 0);
  JD(f, "facet_angle_exceptions", r->facet_exceptions, 0);
  JD(f, "max_hausdorff", r->max_hausdorff, 0);
  JD(f, "max_mesh_to_image", r->max_mesh_to_image, 0);
  JD(f, "max_p99", r->max_p99, 0);
  JD(f, "min_dihedral", r->min_dihedral, 0);
  JD(f, "max_dihedral", r->max_dihedral, 0);
  JD(f, "max_volume_error", r->max_volume_error, 0);
  JI(f, "volume_min_voxels", r->volume_min_voxels, 0);
  JI(f, "require_labels", r->require_labels, 0);
  JI(f, "require_whole", r->require_whole, 1);
  fprintf(f, "}, ");
  JB(f, "passed", r->validity.valid && r->nviol == 0, 0);
  fprintf(f, "\"violations\": [");
  for (int i = 0; i < r->nviol; i++) {
    if (i) fprintf(f, ", ");
    i2m_json_string(f, r->viol[i]);
  }
  fprintf(f, "], \"timings\": {");
  JD(f, "read", r->t_read, 0);
  JD(f, "validity", r->t_validity, 0);
  JD(f, "quality", r->t_quality, 0);
  JD(f, "fidelity", r->t_fidelity, 0);
  if (r->have_fidelity) {
    JD(f, "fidelity_mesh_to_image", r->fidelity.t_mesh_to_image, 0);
    JD(f, "fidelity_image_to_mesh", r->fidelity.t_image_to_mesh, 0);
    JD(f, "fidelity_components", r->fidelity.t_components, 0);
  }
  JD(f, "total", r->t_total, 1);
  fprintf(f, "}}\n");
}

/* ---- text ---- */
static void text_validity(FILE *f, const ck_validity_t *v)
{
  fprintf(f, "validity: %s%s%s%s\n", v->valid ? "VALID" : "INVALID", v->valid ? "" : " (",
          v->valid ? "" : v->errors, v->valid ? "" : ")");
  if (v->bad_index || v->nonfinite) {
    fprintf(f, "  vertex ids out of range: %lld tets (first: tet %lld); vertices with a non-finite "
               "coordinate: %lld (first %lld)\n", (long long)v->bad_index,
            (long long)v->first_bad_index, (long long)v->nonfinite, (long long)v->first_nonfinite);
    return;
  }
  fprintf(f, "  inverted tets %lld (first %lld), zero-volume tets %lld (first %lld)\n",
          (long long)v->inverted, (long long)v->first_inverted, (long long)v->degenerate,
          (long long)v->first_degenerate);
  fprintf(f, "  volume: total %.6g, min %.6g (tet %lld)\n", v->total_volume, v->min_volume,
          (long long)v->min_volume_tet);
  fprintf(f, "  faces: %lld interior, %lld boundary, %lld shared by 3+ tets (first tet %lld), "
             "%lld overlapping (first tet %lld)\n",
          (long long)v->interior_faces, (long long)v->boundary_faces,
          (long long)v->nonmanifold_faces, (long long)v->first_nonmanifold_tet,
          (long long)v->overlapping_faces, (long long)v->first_overlapping_tet);
  fprintf(f, "  vertices: %lld dangling (first %lld), %lld duplicates (first %lld = %lld)\n",
          (long long)v->dangling, (long long)v->first_dangling, (long long)v->duplicate,
          (long long)v->first_duplicate, (long long)v->first_duplicate_of);
  fprintf(f, "  boundary surface: %lld edges, %lld used an odd number of times (%s)\n",
          (long long)v->boundary_edges, (long long)v->boundary_open_edges,
          v->boundary_open_edges ? "OPEN" : "closed");
  fprintf(f, "  interface triangles from the tets: %lld in %lld label pairs\n",
          (long long)v->interface_triangles, (long long)v->interface_pairs);
  if (v->file_triangles || v->tri_bad_index)
    fprintf(f, "  file triangles: %lld; not interfaces %lld, interfaces missing %lld, label pair "
               "mismatches %lld, duplicates %lld, bad ids %lld\n"
               "  file triangle orientation: %s (%lld outward: normal from the higher label to the "
               "lower, out of the domain; %lld inward)\n",
            (long long)v->file_triangles, (long long)v->file_not_interface,
            (long long)v->interface_not_in_file, (long long)v->file_label_mismatch,
            (long long)v->file_duplicate, (long long)v->tri_bad_index, ck_validity_orientation(v),
            (long long)v->file_outward, (long long)v->file_inward);
}

static void text_quality(FILE *f, const ck_quality_t *q)
{
  fprintf(f, "quality:\n  dihedral angles: min %.3f (tet %lld), max %.3f (tet %lld); tets with an "
             "angle < 5: %lld, < 10: %lld, < 15: %lld, < 20: %lld, > 160: %lld, > 170: %lld\n",
          q->min_dihedral, (long long)q->min_dihedral_tet, q->max_dihedral,
          (long long)q->max_dihedral_tet, (long long)q->dihedral_below[0],
          (long long)q->dihedral_below[1], (long long)q->dihedral_below[2], (long long)q->dihedral_below[3],
          (long long)q->dihedral_above[0], (long long)q->dihedral_above[1]);
  fprintf(f, "  radius-edge ratio: max %.4g (tet %lld), mean %.4g, p50 %.4g, p90 %.4g, p99 %.4g, "
             "p99.9 %.4g; above %.4g: %lld, above 2: %lld\n",
          q->max_ratio, (long long)q->max_ratio_tet, q->ratio_mean, q->ratio_p50, q->ratio_p90,
          q->ratio_p99, q->ratio_p999, q->ratio_bound, (long long)q->ratio_above_bound,
          (long long)q->ratio_above_2);
  fprintf(f, "  interface triangles: %lld, min planar angle %.3f (triangle %lld), below %.4g: "
             "%lld, below 30: %lld\n",
          (long long)q->ntri, q->min_planar_angle, (long long)q->min_planar_tri,
          q->facet_angle_bound, (long long)q->planar_below_bound, (long long)q->planar_below_30);
}

static void text_dist(FILE *f, const char *name, const ck_dist_t *d, double sp)
{
  fprintf(f, "  %-14s max %.4g mm (%.3g vox) at (%.4g, %.4g, %.4g), p99 %.4g mm (%.3g vox), "
             "mean %.4g mm (%.3g vox), %lld points\n",
          name, d->max, d->max / sp, d->where[0], d->where[1], d->where[2], d->p99, d->p99 / sp,
          d->mean, d->mean / sp, (long long)d->count);
}

static void text_fidelity(FILE *f, const ck_fidelity_t *x)
{
  fprintf(f, "fidelity (min spacing %.4g mm, sample spacing %.4g mm, %lld image interface faces):\n",
          x->min_spacing, x->sample_spacing, (long long)x->image_faces);
  if (x->distances) {
    text_dist(f, "mesh->image", &x->mesh_to_image, x->min_spacing);
    text_dist(f, "image->mesh", &x->image_to_mesh, x->min_spacing);
    text_dist(f, "two-sided", &x->two_sided, x->min_spacing);
  } else {
    fprintf(f, "  distances not computed (--no-distances)\n");
  }
  if (x->distances) fprintf(f, "  worst image face: labels %lld|%lld, their components %lld|%lld voxels, thinnest runs through it %.3g|%.3g mm\n",
          (long long)x->worst_pair[0], (long long)x->worst_pair[1], (long long)x->worst_component[0],
          (long long)x->worst_component[1], x->worst_thinnest[0], x->worst_thinnest[1]);
  fprintf(f, "  labels: %d, missing from the mesh %lld, not in the image %lld\n", x->nlabels,
          (long long)x->missing_labels, (long long)x->extra_labels);
  fprintf(f, "  %8s %10s %12s %12s %9s %8s %8s %8s %8s %8s\n", "label", "voxels", "image mm3", "mesh mm3",
          "error %", "img cc", "cc>=100", "mesh cc", "large cc", "split");
  for (int i = 0; i < x->nlabels; i++) {
    const ck_label_t *L = &x->labels[i];
    fprintf(f, "  %8lld %10lld %12.5g %12.5g %9.3f %8lld %8lld %8lld %8lld %8lld%s\n", (long long)L->value,
            (long long)L->voxels, L->image_volume, L->mesh_volume, L->rel_error_pct,
            (long long)L->image_components, (long long)L->image_components_100,
            (long long)L->mesh_components, (long long)L->large_components, (long long)L->split_components,
            L->in_mesh ? "" : "  MISSING");
  }
}

static void text_stitch(FILE *f, const ck_stitch_t *st, const ck_mesh_t *m)
{
  for (int p = 0; p < st->npieces; p++)
    fprintf(f, "  piece %d: %s: %lld vertices, %lld tets%s\n", p, st->piece_path[p],
            (long long)st->piece_nv[p], (long long)(st->tet_start[p + 1] - st->tet_start[p]),
            st->piece_has_gid[p] ? "" : ", no GlobalNodeId");
  fprintf(f, "stitch: %d pieces, %lld vertices before merging, %lld after, %lld seam vertices "
             "(global ids in 2+ pieces)", st->npieces, (long long)st->vertices_before,
          (long long)m->nv, (long long)st->seam_vertices);
  if (st->seams_checked)
    fprintf(f, "; %lld boundary faces on seams, %lld seen by one side only",
            (long long)st->seam_boundary_faces, (long long)st->one_sided_faces);
  fprintf(f, "\n");
  stitch_error_t e[4];
  int ne = stitch_errors(st, e);
  for (int i = 0; i < ne; i++)
    fprintf(f, "STITCH ERROR: %s: %lld; first: %s\n", e[i].what, (long long)e[i].count, e[i].first);
}

void ck_report_text(FILE *f, const ck_result_t *r)
{
  const ck_mesh_t *m = r->mesh;
  fprintf(f, "mesh %s (%s): %lld vertices, %lld tetrahedra, %lld file triangles%s\n", r->mesh_path,
          m->format, (long long)m->nv, (long long)m->nt, (long long)m->ntri,
          m->ignored_cells ? " (other cells ignored)" : "");
  if (m->stitch) text_stitch(f, m->stitch, m);
  text_validity(f, &r->validity);
  if (r->have_quality) text_quality(f, &r->quality);
  if (r->have_fidelity) text_fidelity(f, &r->fidelity);
  for (int i = 0; i < r->nviol; i++) fprintf(f, "THRESHOLD VIOLATED: %s\n", r->viol[i]);
  fprintf(f, "time: read %.2f s, validity %.2f s, quality %.2f s, fidelity %.2f s, total %.2f s\n",
          r->t_read, r->t_validity, r->t_quality, r->t_fidelity, r->t_total);
  fprintf(f, "result: %s\n", r->validity.valid && r->nviol == 0 ? "PASS" : "FAIL");
}
