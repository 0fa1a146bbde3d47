# The layering rule of docs/ARCHITECTURE.md ("Layers"), enforced: a file in
# a layer folder includes hmc headers only from its own layer and the
# layers below it. Run as a CTest:
#   cmake -DROOT=<source dir> -DLAYERS=core,synth,... -P CheckLayers.cmake
# LAYERS: the layer folders bottom to top (the top CMakeLists.txt's
# HMC_LAYERS). Folders above every layer (apps, tests, bench) are not
# checked: they may include everything. Fails listing every violation.
if(NOT ROOT OR NOT LAYERS)
  message(FATAL_ERROR "CheckLayers.cmake needs -DROOT=... -DLAYERS=a,b,...")
endif()
string(REPLACE "," ";" layers "${LAYERS}")
set(violations "")
set(checked 0)
list(LENGTH layers count)
math(EXPR last "${count} - 1")
foreach(rank RANGE ${last})
  list(GET layers ${rank} layer)
  file(GLOB_RECURSE files "${ROOT}/${layer}/*.h" "${ROOT}/${layer}/*.cc")
  foreach(file ${files})
    math(EXPR checked "${checked} + 1")
    file(STRINGS "${file}" includes REGEX "^[ \t]*#[ \t]*include[ \t]+\"[a-z_]+/")
    foreach(line ${includes})
      string(REGEX REPLACE "^[ \t]*#[ \t]*include[ \t]+\"([a-z_]+)/.*" "\\1"
             target "${line}")
      list(FIND layers "${target}" target_rank)
      if(target_rank GREATER rank OR
         (target_rank EQUAL -1 AND NOT target STREQUAL layer))
        file(RELATIVE_PATH rel "${ROOT}" "${file}")
        string(STRIP "${line}" line)
        list(APPEND violations "${rel}: ${line} (${layer} is below ${target})")
      endif()
    endforeach()
  endforeach()
endforeach()
if(violations)
  list(JOIN violations "\n  " text)
  message(FATAL_ERROR "layering: a lower layer includes a higher one:\n  ${text}")
endif()
message(STATUS "layering: ${checked} files of ${count} layers include only lower layers")
