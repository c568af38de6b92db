# The native half of the extension: cargo builds libbaffle (C ABI) and the `baffle`
# program, and they are packaged with the `baffle` Python package beside the scripted
# module, where Slicer's Python imports it (the scripted modules' folder is on sys.path):
#
#   <scripted modules dir>/baffle/            the package (python/baffle)
#   <scripted modules dir>/baffle/libbaffle.so (baffle.dll, libbaffle.dylib): loaded by baffle/_lib.py
#   <scripted modules dir>/baffle/bin/baffle   the program: found by BaffleDesignerLib.environment
#
# baffle_designer_add_native(DESTINATION <install dir> [BUILD_DIRECTORY <dir>])
#   DESTINATION: the install tree's scripted modules folder (Slicer_INSTALL_QTSCRIPTEDMODULES_LIB_DIR);
#   BUILD_DIRECTORY: the build tree's one, filled after the build, for a Slicer run from the build tree.

set(BAFFLE_REPOSITORY_DIR "${CMAKE_CURRENT_LIST_DIR}/../../.." CACHE PATH "the baffle repository (Cargo workspace)")
get_filename_component(BAFFLE_REPOSITORY_DIR "${BAFFLE_REPOSITORY_DIR}" ABSOLUTE)
set(BAFFLE_CARGO_TARGET_DIR "${BAFFLE_REPOSITORY_DIR}/target" CACHE PATH
    "cargo --target-dir (shared with cargo test and pip, so the crates build once)")

function(baffle_designer_add_native)
  cmake_parse_arguments(ARG "" "DESTINATION;BUILD_DIRECTORY" "" ${ARGN})
  if(NOT ARG_DESTINATION)
    message(FATAL_ERROR "baffle_designer_add_native: DESTINATION is required")
  endif()
  find_program(CARGO_EXECUTABLE cargo HINTS "$ENV{CARGO_HOME}/bin" "$ENV{HOME}/.cargo/bin")
  if(NOT CARGO_EXECUTABLE)
    message(FATAL_ERROR "cargo not found: the extension builds the baffle library and program with Rust (rustup)")
  endif()
  if(WIN32)
    set(library_name "baffle.dll")  # what baffle/_lib.py loads
  elseif(APPLE)
    set(library_name "libbaffle.dylib")
  else()
    set(library_name "libbaffle.so")
  endif()
  set(out "${BAFFLE_CARGO_TARGET_DIR}/release")
  set(library "${out}/${library_name}")
  set(program "${out}/baffle${CMAKE_EXECUTABLE_SUFFIX}")
  set(package "${BAFFLE_REPOSITORY_DIR}/python/baffle")

  # Cargo decides what is stale, so it runs on every build (a no-op build takes about 1 s).
  add_custom_target(BaffleDesignerNative ALL
    COMMAND "${CARGO_EXECUTABLE}" build --release -p baffle-capi -p baffle-cli --target-dir "${BAFFLE_CARGO_TARGET_DIR}"
    WORKING_DIRECTORY "${BAFFLE_REPOSITORY_DIR}"
    BYPRODUCTS "${library}" "${program}"
    COMMENT "cargo build --release -p baffle-capi -p baffle-cli"
    USES_TERMINAL)

  if(ARG_BUILD_DIRECTORY)
    add_custom_command(TARGET BaffleDesignerNative POST_BUILD
      COMMAND "${CMAKE_COMMAND}" -E copy_directory "${package}" "${ARG_BUILD_DIRECTORY}/baffle"
      COMMAND "${CMAKE_COMMAND}" -E copy "${library}" "${ARG_BUILD_DIRECTORY}/baffle/${library_name}"
      COMMAND "${CMAKE_COMMAND}" -E make_directory "${ARG_BUILD_DIRECTORY}/baffle/bin"
      COMMAND "${CMAKE_COMMAND}" -E copy "${program}" "${ARG_BUILD_DIRECTORY}/baffle/bin/"
      COMMENT "baffle package, library and program into ${ARG_BUILD_DIRECTORY}")
  endif()

  install(DIRECTORY "${package}" DESTINATION "${ARG_DESTINATION}" COMPONENT RuntimeLibraries
    FILES_MATCHING PATTERN "*.py" PATTERN "__pycache__" EXCLUDE)
  install(FILES "${library}" DESTINATION "${ARG_DESTINATION}/baffle" COMPONENT RuntimeLibraries)
  install(PROGRAMS "${program}" DESTINATION "${ARG_DESTINATION}/baffle/bin" COMPONENT RuntimeLibraries)
endfunction()
