# Dependencies, all from Debian's -dev packages (no vendored copies).
find_package(PkgConfig REQUIRED)
pkg_check_modules(ZMQ REQUIRED IMPORTED_TARGET libzmq)
pkg_check_modules(CJSON REQUIRED IMPORTED_TARGET libcjson)
pkg_check_modules(FFTW REQUIRED IMPORTED_TARGET fftw3)
find_package(HDF5 REQUIRED COMPONENTS C)
find_package(OpenMP REQUIRED COMPONENTS C)

find_path(CHOLMOD_INCLUDE_DIR cholmod.h PATH_SUFFIXES suitesparse REQUIRED)
find_library(CHOLMOD_LIBRARY cholmod REQUIRED)
find_library(SUITESPARSECONFIG_LIBRARY suitesparseconfig REQUIRED)
add_library(cosim_cholmod INTERFACE)
target_include_directories(cosim_cholmod INTERFACE ${CHOLMOD_INCLUDE_DIR})
target_link_libraries(cosim_cholmod INTERFACE ${CHOLMOD_LIBRARY} ${SUITESPARSECONFIG_LIBRARY})

add_library(cosim_hdf5 INTERFACE)
target_include_directories(cosim_hdf5 INTERFACE ${HDF5_INCLUDE_DIRS})
target_compile_definitions(cosim_hdf5 INTERFACE ${HDF5_DEFINITIONS})
target_link_libraries(cosim_hdf5 INTERFACE ${HDF5_C_LIBRARIES})

find_library(MATH_LIBRARY m REQUIRED)
