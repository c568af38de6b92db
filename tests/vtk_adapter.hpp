// vtkPolyData <-> baffle C ABI: points, triangle polys and the per-cell label
// array (ModelFaceID). Used by the integration tests; small enough to copy into
// VTK or Slicer loadable code.
#ifndef BAFFLE_VTK_ADAPTER_HPP
#define BAFFLE_VTK_ADAPTER_HPP

#include <baffle.hpp>

#include <vtkPolyData.h>
#include <vtkSmartPointer.h>

namespace baffle_vtk {

// A baffle mesh from polydata whose cells are all triangle polys, labelled by the
// cell array `label_array`; throws std::runtime_error otherwise.
baffle::Mesh to_mesh(vtkPolyData* polydata, const char* label_array = "ModelFaceID");

// Polydata with the mesh's points, triangles and labels (vtkIntArray `label_array`).
vtkSmartPointer<vtkPolyData> to_polydata(const baffle::Mesh& mesh, const char* label_array = "ModelFaceID");

}  // namespace baffle_vtk

#endif
