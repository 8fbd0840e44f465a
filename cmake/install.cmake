# `cmake --install build [--prefix DIR]`: the headless engine as a CMake package (docs/EMBEDDING.md).
#
#   find_package(stroma 0.1 REQUIRED)
#   target_link_libraries(app PRIVATE stroma::engine)
#
# Installs the static libraries of the headless engine (tissue, io, collision, haptics, engine: the
# model, state and tick; scene: the loaders; runtime: the headless runner — no DDS, no GL;
# stroma::engine links all three), their headers under
# include/stroma/ (included as "engine/tick.hpp", the way the engine includes them, or as
# <stroma/engine/tick.hpp>), stromaConfig.cmake with its version file, and the `stroma` CLI.
# The libraries are built with the build's flags: with STROMA_NATIVE (the default) they are for
# CPUs like the build machine's; configure with -DSTROMA_NATIVE=OFF for a portable package.
include(GNUInstallDirs)
include(CMakePackageConfigHelpers)

set(STROMA_INSTALL_CMAKEDIR ${CMAKE_INSTALL_LIBDIR}/cmake/stroma)
set(STROMA_INSTALL_INCLUDEDIR ${CMAKE_INSTALL_INCLUDEDIR}/stroma)

set_target_properties(stroma_tissue PROPERTIES EXPORT_NAME tissue)
set_target_properties(stroma_io PROPERTIES EXPORT_NAME io)
set_target_properties(stroma_collision PROPERTIES EXPORT_NAME collision)
set_target_properties(stroma_haptics PROPERTIES EXPORT_NAME haptics)
set_target_properties(stroma_rigid PROPERTIES EXPORT_NAME rigid)
set_target_properties(stroma_engine_core PROPERTIES EXPORT_NAME engine_core)
set_target_properties(stroma_scene PROPERTIES EXPORT_NAME scene)
set_target_properties(stroma_runtime PROPERTIES EXPORT_NAME runtime)
set_target_properties(stroma_engine PROPERTIES EXPORT_NAME engine)
set_target_properties(cholmod_dep PROPERTIES EXPORT_NAME cholmod)
foreach(t stroma_tissue stroma_io stroma_collision stroma_haptics stroma_rigid stroma_engine_core stroma_scene stroma_runtime stroma_engine)
  target_include_directories(${t} INTERFACE $<INSTALL_INTERFACE:${STROMA_INSTALL_INCLUDEDIR}>
                                            $<INSTALL_INTERFACE:${CMAKE_INSTALL_INCLUDEDIR}>)
endforeach()

install(TARGETS stroma_tissue stroma_io stroma_collision stroma_haptics stroma_rigid stroma_engine_core stroma_scene stroma_runtime
                stroma_engine cholmod_dep
        EXPORT stromaTargets
        ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR}
        INCLUDES DESTINATION ${STROMA_INSTALL_INCLUDEDIR})
foreach(dir tissue io collision haptics rigid engine scene runtime)
  install(DIRECTORY ${PROJECT_SOURCE_DIR}/${dir}/ DESTINATION ${STROMA_INSTALL_INCLUDEDIR}/${dir}
          FILES_MATCHING PATTERN "*.hpp")
endforeach()
install(TARGETS stroma RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR})

install(EXPORT stromaTargets NAMESPACE stroma:: DESTINATION ${STROMA_INSTALL_CMAKEDIR})
configure_package_config_file(${PROJECT_SOURCE_DIR}/cmake/stromaConfig.cmake.in
                              ${PROJECT_BINARY_DIR}/stromaConfig.cmake
                              INSTALL_DESTINATION ${STROMA_INSTALL_CMAKEDIR})
write_basic_package_version_file(${PROJECT_BINARY_DIR}/stromaConfigVersion.cmake
                                 VERSION ${PROJECT_VERSION} COMPATIBILITY SameMinorVersion)
install(FILES ${PROJECT_BINARY_DIR}/stromaConfig.cmake ${PROJECT_BINARY_DIR}/stromaConfigVersion.cmake
        DESTINATION ${STROMA_INSTALL_CMAKEDIR})
