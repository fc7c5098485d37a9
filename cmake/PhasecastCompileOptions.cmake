# Warning and sanitizer flags shared by every Phasecast target.
# phasecast_set_options(<target>) applies them; generated code (protobuf) gets
# the sanitizers but not the warnings we cannot fix.

add_library(phasecast_warnings INTERFACE)
target_compile_options(phasecast_warnings INTERFACE -Wall -Wextra -Wpedantic -Wshadow
                       -Wnon-virtual-dtor -Wold-style-cast -Wcast-align -Woverloaded-virtual
                       -Wimplicit-fallthrough)
if(PHASECAST_WERROR)
  target_compile_options(phasecast_warnings INTERFACE -Werror)
endif()

if(PHASECAST_SANITIZE)
  string(REPLACE "," ";" _phasecast_sanitizers "${PHASECAST_SANITIZE}")
  foreach(s IN LISTS _phasecast_sanitizers)
    if(NOT s MATCHES "^(address|undefined|leak|thread)$")
      message(FATAL_ERROR "PHASECAST_SANITIZE: unknown sanitizer '${s}' (expected address, undefined, leak or thread)")
    endif()
  endforeach()
  add_compile_options(-fsanitize=${PHASECAST_SANITIZE} -fno-omit-frame-pointer -fno-sanitize-recover=all)
  add_link_options(-fsanitize=${PHASECAST_SANITIZE})
  # GCC's -Wmaybe-uninitialized is unreliable under the sanitizers'
  # instrumentation (false positives inside std::regex and std::function of
  # libstdc++ 12 at -O2), and CI makes warnings errors; the normal build keeps it.
  if(CMAKE_CXX_COMPILER_ID STREQUAL "GNU")
    target_compile_options(phasecast_warnings INTERFACE -Wno-maybe-uninitialized)
  endif()
endif()

function(phasecast_set_options target)
  target_link_libraries(${target} PRIVATE phasecast_warnings)
endfunction()
