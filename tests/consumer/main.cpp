// Designs the phantom through the installed library and header-only wrapper.
#include <baffle.hpp>

#include <iostream>

int main() {
  try {
    baffle::require_abi();
    baffle::Phantom phantom = baffle::phantom();
    baffle::Result result = baffle::design(phantom.surface, phantom.suture_points_mm,
                                           baffle::Options().bsa_m2(phantom.bsa_m2));
    std::cout << "baffle " << baffle::version() << ": " << result.baffle().triangles().size() / 3
              << " baffle triangles\n";
    return 0;
  } catch (const baffle::Error& e) {
    std::cerr << "error: " << e.what() << "\n";
    return 1;
  }
}
