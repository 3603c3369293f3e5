# Included through CMAKE_PROJECT_INCLUDE by launch_scripts/setup_env.sh only (never by a
# colcon build against a real ROS install). The ROS 2 PyPI wheels were built in a
# manylinux image, so their *Export.cmake files name Python and numpy include directories
# under /opt/python/cp311-cp311. At the end of configuration, rewrite every imported
# target's include directories to this interpreter's real ones, before CMake checks them.
if(NOT DEFINED FMM_WHEEL_PYTHON_PREFIX)
  set(FMM_WHEEL_PYTHON_PREFIX "/opt/python/cp311-cp311")
endif()

function(fmm_redirect_wheel_paths)
  get_property(_targets DIRECTORY "${CMAKE_SOURCE_DIR}" PROPERTY IMPORTED_TARGETS)
  foreach(_target IN LISTS _targets)
    get_target_property(_dirs ${_target} INTERFACE_INCLUDE_DIRECTORIES)
    if(_dirs AND _dirs MATCHES "${FMM_WHEEL_PYTHON_PREFIX}")
      list(TRANSFORM _dirs REPLACE
        "^${FMM_WHEEL_PYTHON_PREFIX}/include/python[0-9.]+$" "${FMM_PYTHON_INCLUDE_DIR}")
      list(TRANSFORM _dirs REPLACE
        "^${FMM_WHEEL_PYTHON_PREFIX}/lib/python[0-9.]+/site-packages/numpy/_core/include$"
        "${FMM_NUMPY_INCLUDE_DIR}")
      if(_dirs MATCHES "${FMM_WHEEL_PYTHON_PREFIX}")
        message(FATAL_ERROR "fmm: ${_target} still names ${FMM_WHEEL_PYTHON_PREFIX}: ${_dirs}")
      endif()
      set_target_properties(${_target} PROPERTIES INTERFACE_INCLUDE_DIRECTORIES "${_dirs}")
    endif()
  endforeach()
endfunction()

if(CMAKE_SOURCE_DIR STREQUAL CMAKE_CURRENT_SOURCE_DIR)
  cmake_language(DEFER DIRECTORY "${CMAKE_SOURCE_DIR}" CALL fmm_redirect_wheel_paths)
endif()
