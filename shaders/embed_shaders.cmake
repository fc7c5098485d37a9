# Build-time step: turns each GLSL file into a C++ string constant so the
# client binary carries its shaders (no run-time file lookup).
# Usage: cmake -DOUT=<header> -DSHADERS="a.vert|b.frag" -P embed_shaders.cmake
set(_text "#pragma once\n// Generated from shaders/*.glsl by shaders/embed_shaders.cmake; do not edit.\n")
string(APPEND _text "#include <string_view>\nnamespace phasecast::client::shaders {\n")
string(REPLACE "|" ";" SHADERS "${SHADERS}")
foreach(_file IN LISTS SHADERS)
  file(READ ${_file} _source)
  # `#include "NAME"` lines take the text of NAME beside the shader: GLSL has
  # no includes of its own, and bindings.glsl is shared with the C++.
  get_filename_component(_folder ${_file} DIRECTORY)
  string(REGEX MATCHALL "#include \"[^\"]+\"" _includes "${_source}")
  foreach(_include IN LISTS _includes)
    string(REGEX REPLACE "#include \"([^\"]+)\"" "\\1" _name "${_include}")
    file(READ ${_folder}/${_name} _included)
    string(REPLACE "${_include}\n" "${_included}" _source "${_source}")
  endforeach()
  get_filename_component(_name ${_file} NAME)
  string(MAKE_C_IDENTIFIER ${_name} _id)
  string(APPEND _text "inline constexpr std::string_view ${_id} = R\"glsl(${_source})glsl\";\n")
endforeach()
string(APPEND _text "}  // namespace phasecast::client::shaders\n")
file(WRITE ${OUT}.tmp "${_text}")
file(COPY_FILE ${OUT}.tmp ${OUT} ONLY_IF_DIFFERENT)
file(REMOVE ${OUT}.tmp)
