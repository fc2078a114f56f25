# The interface wheels' exported CMake targets name the include directory of the Python they
# were built with (/opt/python/cp311-cp311/include/python3.11, absent here), and CMake refuses a
# target whose INTERFACE_INCLUDE_DIRECTORIES names a missing directory.  Drop such entries from
# every imported target of this directory (generator expressions are kept).
function(swarm_drop_missing_include_dirs)
  get_directory_property(_targets IMPORTED_TARGETS)
  foreach(_t IN LISTS _targets)
    get_target_property(_dirs ${_t} INTERFACE_INCLUDE_DIRECTORIES)
    if(_dirs)
      set(_kept "")
      foreach(_d IN LISTS _dirs)
        if(EXISTS "${_d}" OR _d MATCHES "^\\$<")
          list(APPEND _kept "${_d}")
        endif()
      endforeach()
      set_target_properties(${_t} PROPERTIES INTERFACE_INCLUDE_DIRECTORIES "${_kept}")
    endif()
  endforeach()
endfunction()
