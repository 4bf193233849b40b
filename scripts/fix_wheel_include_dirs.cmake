# Injected with -DCMAKE_PROJECT_INCLUDE=<this file> when building msg_defs (bearing_id_msgs) against the ROS 2
# wheels from PyPI (ros-jazzy-*).
#
# Problem: about 20 exported cmake files in those wheels (share/<pkg>/cmake/export_<pkg>__rosidl_generator_pyExport.cmake)
# carry the wheel-build machine's include dirs, e.g. /opt/python/cp311-cp311/include/python3.11 and
# .../site-packages/numpy/_core/include.  CMake refuses to generate:
#   Imported target "std_msgs::std_msgs__rosidl_generator_py" includes non-existent path ...
#
# Fix (without touching the venv): defer, to the end of the top-level CMakeLists, a pass over every imported target
# that replaces each NON-EXISTENT include dir by the local Python3 include dir (or the local NumPy include dir when
# the path names numpy).  Existing paths and generator expressions are left alone.

function(_bearing_id_fix_imported_include_dirs)
  find_package(Python3 REQUIRED COMPONENTS Interpreter Development NumPy)
  set(_dirs "${CMAKE_SOURCE_DIR}")
  set(_targets "")
  while(_dirs)
    list(POP_FRONT _dirs _d)
    get_directory_property(_t DIRECTORY "${_d}" IMPORTED_TARGETS)
    list(APPEND _targets ${_t})
    get_directory_property(_sub DIRECTORY "${_d}" SUBDIRECTORIES)
    list(APPEND _dirs ${_sub})
  endwhile()
  list(REMOVE_DUPLICATES _targets)
  set(_n 0)
  foreach(_tgt IN LISTS _targets)
    get_target_property(_inc "${_tgt}" INTERFACE_INCLUDE_DIRECTORIES)
    if(NOT _inc)
      continue()
    endif()
    set(_new "")
    set(_changed FALSE)
    foreach(_p IN LISTS _inc)
      if(_p MATCHES "^\\$<" OR EXISTS "${_p}")
        list(APPEND _new "${_p}")
      elseif(_p MATCHES "numpy")
        list(APPEND _new ${Python3_NumPy_INCLUDE_DIRS})
        set(_changed TRUE)
      elseif(_p MATCHES "include/python3")
        list(APPEND _new ${Python3_INCLUDE_DIRS})
        set(_changed TRUE)
      else()
        list(APPEND _new "${_p}")
      endif()
    endforeach()
    if(_changed)
      list(REMOVE_DUPLICATES _new)
      set_target_properties("${_tgt}" PROPERTIES INTERFACE_INCLUDE_DIRECTORIES "${_new}")
      math(EXPR _n "${_n} + 1")
    endif()
  endforeach()
  message(STATUS "bearing_id: rewrote wheel-build include dirs of ${_n} imported target(s) "
                 "to ${Python3_INCLUDE_DIRS};${Python3_NumPy_INCLUDE_DIRS}")
endfunction()

if(CMAKE_SOURCE_DIR STREQUAL PROJECT_SOURCE_DIR AND NOT _BEARING_ID_FIX_DEFERRED)
  set(_BEARING_ID_FIX_DEFERRED TRUE)
  cmake_language(DEFER DIRECTORY "${CMAKE_SOURCE_DIR}" CALL _bearing_id_fix_imported_include_dirs)
endif()
