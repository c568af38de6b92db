#include "vtk_adapter.hpp"

#include <vtkCellArray.h>
#include <vtkCellData.h>
#include <vtkDataArray.h>
#include <vtkDoubleArray.h>
#include <vtkIdTypeArray.h>
#include <vtkIntArray.h>
#include <vtkPoints.h>

#include <stdexcept>
#include <string>

namespace baffle_vtk {
namespace {

std::vector<std::int64_t> as_int64(vtkDataArray* array) {
  std::vector<std::int64_t> out(static_cast<std::size_t>(array->GetNumberOfValues()));
  for (vtkIdType i = 0; i < array->GetNumberOfValues(); ++i)
    out[static_cast<std::size_t>(i)] = static_cast<std::int64_t>(array->GetComponent(i, 0));
  return out;
}

vtkSmartPointer<vtkIdTypeArray> id_array(const std::vector<std::int64_t>& values) {
  auto out = vtkSmartPointer<vtkIdTypeArray>::New();
  out->SetNumberOfValues(static_cast<vtkIdType>(values.size()));
  for (std::size_t i = 0; i < values.size(); ++i) out->SetValue(static_cast<vtkIdType>(i), values[i]);
  return out;
}

}  // namespace

baffle::Mesh to_mesh(vtkPolyData* polydata, const char* label_array) {
  if (polydata == nullptr) throw std::runtime_error("to_mesh: polydata is null");
  // Cell data is indexed over verts, lines, polys and strips; only polys map 1:1.
  if (polydata->GetNumberOfCells() != polydata->GetNumberOfPolys())
    throw std::runtime_error("to_mesh: polydata has vertices, lines or strips besides polygons");
  vtkDataArray* labels = polydata->GetCellData()->GetArray(label_array);
  if (labels == nullptr) throw std::runtime_error(std::string("to_mesh: no cell array ") + label_array);

  std::vector<double> points(3 * static_cast<std::size_t>(polydata->GetNumberOfPoints()));
  for (vtkIdType i = 0; i < polydata->GetNumberOfPoints(); ++i) polydata->GetPoint(i, &points[3 * i]);
  std::vector<std::int32_t> cell_labels(static_cast<std::size_t>(labels->GetNumberOfTuples()));
  for (vtkIdType i = 0; i < labels->GetNumberOfTuples(); ++i)
    cell_labels[static_cast<std::size_t>(i)] = static_cast<std::int32_t>(labels->GetComponent(i, 0));
  vtkCellArray* polys = polydata->GetPolys();
  return baffle::Mesh::from_vtk_arrays(points, as_int64(polys->GetOffsetsArray()),
                                       as_int64(polys->GetConnectivityArray()), cell_labels);
}

vtkSmartPointer<vtkPolyData> to_polydata(const baffle::Mesh& mesh, const char* label_array) {
  const std::vector<double> coords = mesh.points_mm();
  const std::vector<std::int64_t> triangles = mesh.triangles();
  const std::vector<std::int32_t> labels = mesh.labels();

  auto point_data = vtkSmartPointer<vtkDoubleArray>::New();
  point_data->SetNumberOfComponents(3);
  point_data->SetNumberOfTuples(static_cast<vtkIdType>(coords.size() / 3));
  std::copy(coords.begin(), coords.end(), point_data->GetPointer(0));
  auto points = vtkSmartPointer<vtkPoints>::New();
  points->SetData(point_data);

  std::vector<std::int64_t> offsets(labels.size() + 1);
  for (std::size_t t = 0; t < offsets.size(); ++t) offsets[t] = static_cast<std::int64_t>(3 * t);
  auto polys = vtkSmartPointer<vtkCellArray>::New();
  polys->SetData(id_array(offsets), id_array(triangles));

  auto cell_labels = vtkSmartPointer<vtkIntArray>::New();
  cell_labels->SetName(label_array);
  cell_labels->SetNumberOfValues(static_cast<vtkIdType>(labels.size()));
  std::copy(labels.begin(), labels.end(), cell_labels->GetPointer(0));

  auto polydata = vtkSmartPointer<vtkPolyData>::New();
  polydata->SetPoints(points);
  polydata->SetPolys(polys);
  polydata->GetCellData()->AddArray(cell_labels);
  return polydata;
}

}  // namespace baffle_vtk
