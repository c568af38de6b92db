// Header-only C++17 wrapper of the baffle C ABI (baffle.h): RAII handles, values
// in std::vector, and exceptions carrying the library's message, so C++ callers
// never free by hand.
#ifndef BAFFLE_HPP
#define BAFFLE_HPP

#include "baffle.h"

#include <cstdint>
#include <exception>
#include <functional>
#include <memory>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace baffle {

// A failed call: the status code and the library's message.
class Error : public std::runtime_error {
 public:
  Error(BaffleStatus status, const std::string& message) : std::runtime_error(message), status_(status) {}
  BaffleStatus status() const noexcept { return status_; }

 private:
  BaffleStatus status_;
};

// The progress callback asked to stop.
class Cancelled : public Error {
 public:
  using Error::Error;
};

namespace detail {

inline void check(BaffleStatus status) {
  if (status == BAFFLE_STATUS_OK) return;
  std::string message = baffle_last_error();
  if (status == BAFFLE_STATUS_CANCELLED) throw Cancelled(status, message);
  throw Error(status, message);
}

struct MeshDeleter {
  void operator()(BaffleMesh* m) const noexcept { baffle_mesh_free(m); }
};
struct ResultDeleter {
  void operator()(BaffleResult* r) const noexcept { baffle_result_free(r); }
};
struct FreeDeleter {
  void operator()(void* p) const noexcept { baffle_free(p); }
};
struct TemplateDeleter {
  void operator()(BaffleTemplate* t) const noexcept { baffle_template_free(t); }
};

// A NUL-terminated string the library allocated, copied and freed.
inline std::string take_string(char* raw) {
  std::unique_ptr<char, FreeDeleter> owned(raw);
  return std::string(owned.get());
}

// A byte array the library allocated, copied and freed.
inline std::vector<std::uint8_t> take_bytes(std::uint8_t* raw, std::size_t len) {
  std::unique_ptr<std::uint8_t, FreeDeleter> owned(raw);
  return std::vector<std::uint8_t>(raw, raw + len);
}

// Query a count, then copy that many elements (times `per_item`) into a vector.
template <typename T, typename Handle, typename CountFn, typename CopyFn>
std::vector<T> copy_out(const Handle* handle, CountFn count_fn, CopyFn copy_fn, std::size_t per_item) {
  std::size_t n = 0;
  check(count_fn(handle, &n));
  std::vector<T> out(n * per_item);
  check(copy_fn(handle, out.data(), out.size()));
  return out;
}

}  // namespace detail

// Library and ABI versions; throws if the loaded library's ABI is not this header's.
inline std::string version() { return baffle_version(); }
inline void require_abi() {
  if (baffle_abi_version() != BAFFLE_ABI_VERSION)
    throw Error(BAFFLE_STATUS_UNSUPPORTED_VERSION, "libbaffle ABI " + std::to_string(baffle_abi_version()) +
                                                       " does not match baffle.h ABI " +
                                                       std::to_string(BAFFLE_ABI_VERSION));
}

// A labelled triangle surface (mm); cheap to move, immutable.
class Mesh {
 public:
  // points: x y z per point; triangles: 3 indices each; labels: one per triangle.
  static Mesh from_arrays(const std::vector<double>& points_mm, const std::vector<std::int64_t>& triangles,
                          const std::vector<std::int32_t>& labels) {
    BaffleMesh* m = nullptr;
    detail::check(baffle_mesh_new(points_mm.data(), points_mm.size(), triangles.data(), triangles.size(),
                                  labels.data(), labels.size(), &m));
    return Mesh(m);
  }

  // VTK's polygon layout: offsets (cells + 1) and connectivity; triangles only.
  static Mesh from_vtk_arrays(const std::vector<double>& points_mm, const std::vector<std::int64_t>& offsets,
                              const std::vector<std::int64_t>& connectivity, const std::vector<std::int32_t>& labels) {
    BaffleMesh* m = nullptr;
    detail::check(baffle_mesh_new_vtk(points_mm.data(), points_mm.size(), offsets.data(), offsets.size(),
                                      connectivity.data(), connectivity.size(), labels.data(), labels.size(), &m));
    return Mesh(m);
  }

  // Takes ownership of a handle from the C ABI.
  explicit Mesh(BaffleMesh* handle) : handle_(handle) {}

  std::vector<double> points_mm() const {
    return detail::copy_out<double>(get(), baffle_mesh_point_count, baffle_mesh_copy_points, 3);
  }
  std::vector<std::int64_t> triangles() const {
    return detail::copy_out<std::int64_t>(get(), baffle_mesh_triangle_count, baffle_mesh_copy_triangles, 3);
  }
  std::vector<std::int32_t> labels() const {
    return detail::copy_out<std::int32_t>(get(), baffle_mesh_triangle_count, baffle_mesh_copy_labels, 1);
  }
  const BaffleMesh* get() const noexcept { return handle_.get(); }

 private:
  std::unique_ptr<BaffleMesh, detail::MeshDeleter> handle_;
};

// Design options: the paper's defaults; set a target before designing.
class Options {
 public:
  Options() { detail::check(baffle_design_options_init(&raw_)); }
  Options& bsa_m2(double bsa, double z_score = 0.0) {
    raw_.target_kind = BAFFLE_TARGET_KIND_BSA;
    raw_.bsa_m2 = bsa;
    raw_.z_score = z_score;
    return *this;
  }
  Options& target_area_mm2(double area) {
    raw_.target_kind = BAFFLE_TARGET_KIND_AREA_MM2;
    raw_.target_area_mm2 = area;
    return *this;
  }
  Options& annulus_diameter_mm(double diameter) {
    raw_.target_kind = BAFFLE_TARGET_KIND_ANNULUS_DIAMETER_MM;
    raw_.annulus_diameter_mm = diameter;
    return *this;
  }
  // The patient's peak flow (ml/s): the report then holds hemodynamics_estimate.
  Options& peak_flow_ml_s(double q) {
    raw_.peak_flow_ml_s = q;
    return *this;
  }
  // Hold the tunnel's sections normal to the flow at the target too (--flow-sections).
  Options& flow_sections(bool on = true) {
    raw_.flow_sections = on ? 1 : 0;
    return *this;
  }
  BaffleDesignOptions& raw() noexcept { return raw_; }
  const BaffleDesignOptions& raw() const noexcept { return raw_; }

 private:
  BaffleDesignOptions raw_{};
};

struct Centerline {
  std::vector<double> points_mm, tangents, s_mm;
};

// One centerline section: plane through origin with unit normal; only
// constrained sections are promised to reach the target area.
struct Section {
  double s_mm;
  double origin_mm[3];
  double normal[3];
  bool constrained;
  double final_area_mm2;  // NaN where not measured
};

class Result {
 public:
  explicit Result(BaffleResult* handle) : handle_(handle) {}

  Mesh domain() const { return take_mesh(baffle_result_domain); }
  Mesh baffle() const { return take_mesh(baffle_result_baffle); }
  double target_area_mm2() const {
    double area = 0.0;
    detail::check(baffle_result_target_area_mm2(get(), &area));
    return area;
  }
  std::string report_json() const {
    char* raw = nullptr;
    detail::check(baffle_result_report_json(get(), &raw));
    return detail::take_string(raw);
  }
  std::vector<double> seam_mm() const {
    return detail::copy_out<double>(get(), baffle_result_seam_count, baffle_result_copy_seam, 3);
  }
  Centerline centerline() const {
    std::size_t n = 0;
    detail::check(baffle_result_centerline_count(get(), &n));
    Centerline c{std::vector<double>(3 * n), std::vector<double>(3 * n), std::vector<double>(n)};
    detail::check(baffle_result_copy_centerline(get(), c.points_mm.data(), c.tangents.data(), c.s_mm.data(), n));
    return c;
  }
  std::vector<Section> sections() const;
  const BaffleResult* get() const noexcept { return handle_.get(); }

 private:
  template <typename Getter>
  Mesh take_mesh(Getter getter) const {
    BaffleMesh* m = nullptr;
    detail::check(getter(get(), &m));
    return Mesh(m);
  }
  std::unique_ptr<BaffleResult, detail::ResultDeleter> handle_;
};

inline std::vector<Section> Result::sections() const {
  std::size_t n = 0;
  detail::check(baffle_result_section_count(get(), &n));
  std::vector<double> s(n), origins(3 * n), normals(3 * n), areas(n);
  std::vector<std::int32_t> constrained(n);
  detail::check(baffle_result_copy_sections(get(), s.data(), origins.data(), normals.data(), constrained.data(),
                                            areas.data(), n));
  std::vector<Section> out(n);
  for (std::size_t k = 0; k < n; ++k) {
    out[k] = Section{s[k], {origins[3 * k], origins[3 * k + 1], origins[3 * k + 2]},
                     {normals[3 * k], normals[3 * k + 1], normals[3 * k + 2]}, constrained[k] != 0, areas[k]};
  }
  return out;
}

// (fraction done, stage name) -> keep going?
using Progress = std::function<bool(double, const std::string&)>;

namespace detail {

// Carries the C++ callback through the C ABI; an exception it throws cancels the
// call and is rethrown once the call has returned (it must not cross the ABI).
struct ProgressTrampoline {
  const Progress* progress;
  std::exception_ptr error;

  static std::int32_t call(double fraction, const char* stage, void* user) noexcept {
    auto* self = static_cast<ProgressTrampoline*>(user);
    try {
      return (*self->progress)(fraction, stage) ? 1 : 0;
    } catch (...) {
      self->error = std::current_exception();
      return 0;
    }
  }
};

}  // namespace detail

// Design the baffle; suture points x y z per point, in the surface's frame.
inline Result design(const Mesh& surface, const std::vector<double>& suture_points_mm, const Options& options,
                     const Progress& progress = nullptr) {
  BaffleResult* raw = nullptr;
  detail::ProgressTrampoline trampoline{&progress, nullptr};
  BaffleProgressFn callback = progress ? &detail::ProgressTrampoline::call : nullptr;
  BaffleStatus status = baffle_design(surface.get(), suture_points_mm.data(), suture_points_mm.size(), &options.raw(),
                                      callback, &trampoline, &raw);
  if (trampoline.error) std::rethrow_exception(trampoline.error);
  detail::check(status);
  return Result(raw);
}

// Suture points from a file (.mrk.json, .fcsv, ...), converted into `frame`.
inline std::vector<double> read_suture_points(const std::string& path, BaffleFrame frame = BAFFLE_FRAME_LPS) {
  double* raw = nullptr;
  std::size_t len = 0;
  detail::check(baffle_read_suture_points(path.c_str(), frame, &raw, &len));
  std::unique_ptr<double, detail::FreeDeleter> owned(raw);
  return std::vector<double>(raw, raw + len);
}

// The built-in synthetic phantom: surface, suture points and its BSA (m2).
struct Phantom {
  Mesh surface;
  std::vector<double> suture_points_mm;
  double bsa_m2;
};

inline Phantom phantom() {
  BaffleMesh* surface = nullptr;
  double* points = nullptr;
  std::size_t len = 0;
  double bsa_m2 = 0.0;
  detail::check(baffle_phantom(&surface, &points, &len, &bsa_m2));
  std::unique_ptr<double, detail::FreeDeleter> owned(points);
  return Phantom{Mesh(surface), std::vector<double>(points, points + len), bsa_m2};
}

// The ModelFaceIDs a template reads from a designed domain (baffle_design's defaults).
struct TemplateLabels {
  std::int32_t baffle = 10, vsd_cap = 11, aortic_cap = 16;
};

// The true-scale patch template of a designed domain: the baffle flattened (scaled to
// the seam length), its report and the printable A4 page; immutable, cheap to move.
class Template {
 public:
  // Suture points x y z per point in the domain's frame, named by `point_labels` (empty:
  // 1, 2, ...); an empty `date` prints today (UTC).
  static Template flatten(const Mesh& domain, const std::vector<double>& suture_points_mm,
                          const std::vector<std::string>& point_labels = {}, const std::string& patient_label = "",
                          const std::string& date = "", BaffleFlattenMethod method = BAFFLE_FLATTEN_METHOD_LSCM,
                          const TemplateLabels& labels = {}) {
    std::string names;
    for (std::size_t k = 0; k < point_labels.size(); ++k) names += (k ? "\n" : "") + point_labels[k];
    const std::int32_t ids[3] = {labels.baffle, labels.vsd_cap, labels.aortic_cap};
    BaffleTemplate* t = nullptr;
    detail::check(baffle_template(domain.get(), suture_points_mm.data(), suture_points_mm.size(),
                                  point_labels.empty() ? nullptr : names.c_str(), patient_label.c_str(),
                                  date.empty() ? nullptr : date.c_str(), ids, method, &t));
    return Template(t);
  }

  // Takes ownership of a handle from the C ABI.
  explicit Template(BaffleTemplate* handle) : handle_(handle) {}

  // The flattened baffle: points (u, v, 0) mm, the baffle's triangles.
  Mesh flat_mesh() const {
    BaffleMesh* m = nullptr;
    detail::check(baffle_template_flat_mesh(get(), &m));
    return Mesh(m);
  }
  // "flattening" (seam length, perimeter and its error, distortion), per point and per triangle.
  std::string report_json() const {
    char* raw = nullptr;
    detail::check(baffle_template_report_json(get(), &raw));
    return detail::take_string(raw);
  }
  // The page's bytes as the file holds them (PDF, SVG, or PNG at 300 dpi).
  std::vector<std::uint8_t> document(BaffleTemplateFormat format) const {
    std::uint8_t* raw = nullptr;
    std::size_t len = 0;
    detail::check(baffle_template_document(get(), format, &raw, &len));
    return detail::take_bytes(raw, len);
  }
  // The page as a PNG at `dpi` (stored in its pHYs chunk).
  std::vector<std::uint8_t> png(double dpi) const {
    std::uint8_t* raw = nullptr;
    std::size_t len = 0;
    detail::check(baffle_template_png(get(), dpi, &raw, &len));
    return detail::take_bytes(raw, len);
  }
  const BaffleTemplate* get() const noexcept { return handle_.get(); }

 private:
  std::unique_ptr<BaffleTemplate, detail::TemplateDeleter> handle_;
};

}  // namespace baffle

#endif  // BAFFLE_HPP
