/* The C ABI from C: error paths return codes and messages and the process keeps
 * going; the phantom design runs and every getter's output is freed. Run plain
 * and under valgrind (no leaks, no invalid accesses). */
#include "baffle.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static int failures = 0;

#define CHECK(cond, ...)                                  \
  do {                                                    \
    if (!(cond)) {                                        \
      fprintf(stderr, "%s:%d: FAILED %s: ", __FILE__, __LINE__, #cond); \
      fprintf(stderr, __VA_ARGS__);                       \
      fprintf(stderr, "\n");                              \
      failures++;                                         \
    }                                                     \
  } while (0)

/* The status is `expected` and the message mentions `fragment`. */
static void expect_error(BaffleStatus status, BaffleStatus expected, const char *fragment) {
  CHECK(status == expected, "status %d, expected %d (%s)", (int)status, (int)expected, baffle_last_error());
  CHECK(strstr(baffle_last_error(), fragment) != NULL, "message \"%s\" lacks \"%s\"", baffle_last_error(), fragment);
}

/* A tetrahedron with every label the design needs. */
static const double tetra_points[12] = {0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1};
static const int64_t tetra_triangles[12] = {0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3};
static const int32_t tetra_labels[4] = {2, 2, 11, 16};

static void bsa_options(BaffleDesignOptions *options, double bsa_m2) {
  CHECK(baffle_design_options_init(options) == BAFFLE_STATUS_OK, "%s", baffle_last_error());
  options->target_kind = BAFFLE_TARGET_KIND_BSA;
  options->bsa_m2 = bsa_m2;
}

static void test_argument_errors(void) {
  BaffleMesh *mesh = NULL;
  double nan_points[12];
  int64_t bad_triangles[12];
  size_t count = 0;
  memcpy(nan_points, tetra_points, sizeof nan_points);
  nan_points[7] = NAN;
  memcpy(bad_triangles, tetra_triangles, sizeof bad_triangles);
  bad_triangles[4] = 99;

  expect_error(baffle_mesh_new(NULL, 12, tetra_triangles, 12, tetra_labels, 4, &mesh), BAFFLE_STATUS_NULL_POINTER,
               "points_mm is NULL");
  expect_error(baffle_mesh_new(tetra_points, 12, tetra_triangles, 12, tetra_labels, 4, NULL),
               BAFFLE_STATUS_NULL_POINTER, "out_mesh");
  expect_error(baffle_mesh_new(nan_points, 12, tetra_triangles, 12, tetra_labels, 4, &mesh),
               BAFFLE_STATUS_INVALID_ARGUMENT, "non-finite");
  expect_error(baffle_mesh_new(tetra_points, 12, bad_triangles, 12, tetra_labels, 4, &mesh),
               BAFFLE_STATUS_INVALID_ARGUMENT, "refers to point 99");
  expect_error(baffle_mesh_new(tetra_points, 10, tetra_triangles, 12, tetra_labels, 4, &mesh),
               BAFFLE_STATUS_INVALID_ARGUMENT, "not a multiple of 3");
  CHECK(mesh == NULL, "no mesh after a failure");
  expect_error(baffle_mesh_point_count(NULL, &count), BAFFLE_STATUS_NULL_POINTER, "mesh is NULL");
  expect_error(baffle_result_report_json(NULL, NULL), BAFFLE_STATUS_NULL_POINTER, "NULL");
  expect_error(baffle_read_suture_points("/nonexistent/points.mrk.json", BAFFLE_FRAME_LPS, &(double *){NULL}, &count),
               BAFFLE_STATUS_IO, "/nonexistent/points.mrk.json");
  baffle_mesh_free(NULL);
  baffle_result_free(NULL);
  baffle_free(NULL);
}

static void test_open_mesh_and_too_few_points(void) {
  BaffleMesh *open = NULL, *surface = NULL;
  BaffleResult *result = NULL;
  BaffleDesignOptions options;
  double *points = NULL, bsa_m2 = 0;
  size_t len = 0;
  bsa_options(&options, 0.37);
  /* Without the first wall triangle the tetrahedron has a hole. */
  CHECK(baffle_mesh_new(tetra_points, 12, tetra_triangles + 3, 9, tetra_labels + 1, 3, &open) == BAFFLE_STATUS_OK,
        "%s", baffle_last_error());
  expect_error(baffle_design(open, tetra_points, 12, &options, NULL, NULL, &result), BAFFLE_STATUS_INVALID_INPUT,
               "not a closed manifold");
  baffle_mesh_free(open);

  CHECK(baffle_phantom(&surface, &points, &len, &bsa_m2) == BAFFLE_STATUS_OK, "%s", baffle_last_error());
  expect_error(baffle_design(surface, points, 6, &options, NULL, NULL, &result), BAFFLE_STATUS_INVALID_INPUT,
               "at least 4");
  expect_error(baffle_design(surface, NULL, 0, &options, NULL, NULL, &result), BAFFLE_STATUS_NULL_POINTER,
               "suture_points_mm");
  options.struct_size = 4;
  expect_error(baffle_design(surface, points, len, &options, NULL, NULL, &result), BAFFLE_STATUS_UNSUPPORTED_VERSION,
               "struct_size");
  CHECK(result == NULL, "no result after failures");
  baffle_free(points);
  baffle_mesh_free(surface);
}

static int stages_seen = 0;
static int32_t count_stages(double fraction, const char *stage, void *user) {
  (void)user;
  CHECK(fraction >= 0.0 && fraction <= 1.0 && stage[0] != '\0', "fraction %g, stage \"%s\"", fraction, stage);
  stages_seen++;
  return 1;
}

static void test_phantom_design(void) {
  BaffleMesh *surface = NULL, *domain = NULL;
  BaffleResult *result = NULL;
  BaffleDesignOptions options;
  double *points = NULL, bsa_m2 = 0, target_mm2 = 0;
  size_t len = 0, n_points = 0, n_sections = 0, k;
  char *json = NULL;
  CHECK(baffle_phantom(&surface, &points, &len, &bsa_m2) == BAFFLE_STATUS_OK, "%s", baffle_last_error());
  bsa_options(&options, bsa_m2);
  CHECK(baffle_design(surface, points, len, &options, count_stages, NULL, &result) == BAFFLE_STATUS_OK, "%s",
        baffle_last_error());
  baffle_free(points);
  baffle_mesh_free(surface);
  if (result == NULL) return;
  CHECK(stages_seen >= 9, "%d progress calls", stages_seen);

  CHECK(baffle_result_domain(result, &domain) == BAFFLE_STATUS_OK, "%s", baffle_last_error());
  CHECK(baffle_mesh_point_count(domain, &n_points) == BAFFLE_STATUS_OK && n_points > 100, "%zu points", n_points);
  {
    double *coords = malloc(3 * n_points * sizeof *coords);
    expect_error(baffle_mesh_copy_points(domain, coords, 3 * n_points - 1), BAFFLE_STATUS_BUFFER_TOO_SMALL, "needed");
    CHECK(baffle_mesh_copy_points(domain, coords, 3 * n_points) == BAFFLE_STATUS_OK, "%s", baffle_last_error());
    free(coords);
  }
  baffle_mesh_free(domain);

  CHECK(baffle_result_report_json(result, &json) == BAFFLE_STATUS_OK, "%s", baffle_last_error());
  CHECK(json != NULL && strstr(json, "\"sections\"") != NULL, "report has sections");
  baffle_free(json);

  CHECK(baffle_result_target_area_mm2(result, &target_mm2) == BAFFLE_STATUS_OK, "%s", baffle_last_error());
  CHECK(baffle_result_section_count(result, &n_sections) == BAFFLE_STATUS_OK && n_sections > 0, "%zu", n_sections);
  {
    double *s = malloc(n_sections * sizeof *s), *o = malloc(3 * n_sections * sizeof *o);
    double *nrm = malloc(3 * n_sections * sizeof *nrm), *area = malloc(n_sections * sizeof *area);
    int32_t *constrained = malloc(n_sections * sizeof *constrained);
    int n_constrained = 0;
    CHECK(baffle_result_copy_sections(result, s, o, nrm, constrained, area, n_sections) == BAFFLE_STATUS_OK, "%s",
          baffle_last_error());
    for (k = 0; k < n_sections; k++) {
      if (!constrained[k]) continue;
      n_constrained++;
      CHECK(area[k] >= target_mm2, "section at s = %g mm: %g < %g mm2", s[k], area[k], target_mm2);
    }
    CHECK(n_constrained > 0, "some sections are constrained");
    free(s), free(o), free(nrm), free(area), free(constrained);
  }
  baffle_result_free(result);
}

/* The plan's options and the plan's CFD case for a front end's own mesh (the plan itself
 * meshes with gmsh and runs for seconds: the Rust, Python and Slicer tests run it). */
static void test_plan_options_and_case(void) {
  BafflePlanOptions options;
  BafflePlanResult *result = NULL;
  char *path = NULL;
  char text[4096] = {0};
  FILE *file;
  CHECK(baffle_plan_options_init(&options) == BAFFLE_STATUS_OK, "%s", baffle_last_error());
  CHECK(options.struct_size == sizeof options && options.mode == BAFFLE_PLAN_MODE_PULSATILE, "plan defaults");
  /* The target fields appended after the first layout: not given (the BSA's annulus at z 0). */
  CHECK(isnan(options.z_score) && isnan(options.target_area_mm2) && isnan(options.annulus_diameter_mm), "plan target defaults");
  options.phantom = 1;
  options.sbp_mmhg = 107;
  options.dbp_mmhg = 78;
  options.mode = BAFFLE_PLAN_MODE_QUICK;
  expect_error(baffle_plan(&options, NULL, NULL, NULL, &result), BAFFLE_STATUS_NULL_POINTER, "options.out_dir");
  CHECK(result == NULL, "no plan result after a failure");
  /* Two targets are refused in the plan's words before any stage runs (nothing written). */
  options.out_dir = "capi_test_two_targets";
  options.target_area_mm2 = 120;
  options.annulus_diameter_mm = 12;
  expect_error(baffle_plan(&options, NULL, NULL, NULL, &result), BAFFLE_STATUS_INVALID_ARGUMENT, "give one target");
  CHECK(result == NULL && fopen("capi_test_two_targets/report.json", "r") == NULL, "no plan of two targets");
  options.out_dir = NULL;
  options.target_area_mm2 = NAN;
  options.annulus_diameter_mm = NAN;
  CHECK(baffle_plan_write_case(&options, "volume.vtu", "volume-faces.vtp", ".", &path) == BAFFLE_STATUS_OK, "%s",
        baffle_last_error());
  file = path ? fopen(path, "r") : NULL;
  CHECK(file != NULL, "case written at %s", path ? path : "(null)");
  if (file) {
    CHECK(fread(text, 1, sizeof text - 1, file) > 0, "case readable");
    fclose(file);
  }
  CHECK(strstr(text, "\"quick\"") != NULL && strstr(text, "\"volume.vtu\"") != NULL, "case: %s", text);
  baffle_free(path);
  options.dbp_mmhg = 200;
  expect_error(baffle_plan_write_case(&options, "volume.vtu", "volume-faces.vtp", ".", NULL), BAFFLE_STATUS_INVALID_ARGUMENT,
               "exceeds SBP");
}

int main(void) {
  CHECK(baffle_abi_version() == BAFFLE_ABI_VERSION, "ABI %u", baffle_abi_version());
  printf("libbaffle %s (ABI %u)\n", baffle_version(), baffle_abi_version());
  test_argument_errors();
  test_open_mesh_and_too_few_points();
  test_phantom_design();
  test_plan_options_and_case();
  if (failures) fprintf(stderr, "%d check(s) failed\n", failures);
  else printf("all C ABI checks passed\n");
  return failures ? 1 : 0;
}
