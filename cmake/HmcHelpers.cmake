# Every hmc target is declared through these helpers so that all of them get
# the same warnings, sanitizer flags and test wiring.

set(HMC_WARNING_FLAGS -Wall -Wextra -Werror)
set(HMC_SANITIZER_FLAGS -fsanitize=address,undefined -fno-omit-frame-pointer
    -fno-sanitize-recover=undefined)

# HMC_FUZZ (clang): coverage for libFuzzer plus ASan/UBSan in every target;
# warnings stay on but are not errors (the gate is the g++ build).
set(HMC_FUZZ_FLAGS -fsanitize=fuzzer-no-link,address,undefined -fno-omit-frame-pointer
    -fno-sanitize-recover=undefined)
if(HMC_FUZZ)
  set(HMC_WARNING_FLAGS -Wall -Wextra)
endif()

function(hmc_target_common target)
  target_compile_options(${target} PRIVATE ${HMC_WARNING_FLAGS})
  if(HMC_FUZZ)
    target_compile_options(${target} PRIVATE ${HMC_FUZZ_FLAGS})
  endif()
  if(HMC_SANITIZE)
    target_compile_options(${target} PRIVATE ${HMC_SANITIZER_FLAGS})
    target_link_options(${target} PRIVATE ${HMC_SANITIZER_FLAGS})
    # Eigen stops trusting malloc's 16-byte alignment under ASan and pads
    # its blocks itself (handmade_aligned_malloc), but Debian's libceres.a,
    # built without ASan, carries out-of-line copies of Eigen's aligned_malloc
    # that trust it. The linker keeps one copy of each inline function, so a
    # matrix could be allocated by Ceres' copy and freed by ours: a
    # heap-buffer-overflow report. Every target takes Ceres' side (ASan's
    # malloc returns 16-byte-aligned blocks on x86-64, as glibc's does).
    target_compile_definitions(${target} PRIVATE EIGEN_MALLOC_ALREADY_ALIGNED=1)
  endif()
endfunction()

# hmc_add_library(NAME <target> [PUBLIC_DEPS ...] [PRIVATE_DEPS ...]
#                 [TEST_DEPS ...] [NO_UNITY file.cc ...])
# Sources: every *.cc in the calling folder that is not a *_test.cc.
# Tests: every *_test.cc in the folder becomes one GoogleTest binary
# <target>_test, registered with CTest.
# NO_UNITY: files of the folder compiled on their own when the tree is a
# unity build (-DCMAKE_UNITY_BUILD=ON, as scripts/test builds): each one
# clashes with another file of the target in one unit, mostly a name both
# define in their anonymous namespace (docs/PERFORMANCE.md, "The test command").
function(hmc_add_library)
  cmake_parse_arguments(ARG "" "NAME" "PUBLIC_DEPS;PRIVATE_DEPS;TEST_DEPS;NO_UNITY" ${ARGN})
  file(GLOB sources CONFIGURE_DEPENDS ${CMAKE_CURRENT_SOURCE_DIR}/*.cc)
  file(GLOB tests CONFIGURE_DEPENDS ${CMAKE_CURRENT_SOURCE_DIR}/*_test.cc)
  if(tests)
    list(REMOVE_ITEM sources ${tests})
  endif()
  foreach(file ${ARG_NO_UNITY})
    if(NOT EXISTS ${CMAKE_CURRENT_SOURCE_DIR}/${file})
      message(FATAL_ERROR "${ARG_NAME}: NO_UNITY lists ${file}, not a file of this folder")
    endif()
    set_source_files_properties(${CMAKE_CURRENT_SOURCE_DIR}/${file}
      PROPERTIES SKIP_UNITY_BUILD_INCLUSION ON)
  endforeach()
  add_library(${ARG_NAME} STATIC ${sources})
  target_include_directories(${ARG_NAME} PUBLIC ${PROJECT_SOURCE_DIR})
  target_link_libraries(${ARG_NAME} PUBLIC ${ARG_PUBLIC_DEPS} PRIVATE ${ARG_PRIVATE_DEPS})
  hmc_target_common(${ARG_NAME})
  if(HMC_BUILD_TESTS AND tests)
    hmc_add_test(NAME ${ARG_NAME}_test SOURCES ${tests} DEPS ${ARG_NAME} ${ARG_TEST_DEPS})
  endif()
endfunction()

# hmc_add_test(NAME <target> SOURCES ... [DEPS ...] [LABELS ...])
# LABELS: CTest labels of every test of the binary; `slow` ones are left out
# of the sanitizer run of scripts/test (the Release run has them all) and are
# exempt from its 60 s budget per test (docs/PERFORMANCE.md).
function(hmc_add_test)
  cmake_parse_arguments(ARG "" "NAME" "SOURCES;DEPS;LABELS" ${ARGN})
  add_executable(${ARG_NAME} ${ARG_SOURCES})
  target_link_libraries(${ARG_NAME} PRIVATE ${ARG_DEPS} GTest::gtest GTest::gtest_main)
  hmc_target_common(${ARG_NAME})
  set(properties ENVIRONMENT "HMC_SOURCE_DIR=${PROJECT_SOURCE_DIR}")
  if(ARG_LABELS)
    list(APPEND properties LABELS "${ARG_LABELS}")
  endif()
  # ctest -j starts the costliest tests first; a cold tree has no cost data
  # yet, so the long `slow` ones would otherwise start last and run alone.
  if("slow" IN_LIST ARG_LABELS)
    list(APPEND properties COST 1000)
  endif()
  gtest_discover_tests(${ARG_NAME}
    WORKING_DIRECTORY ${PROJECT_SOURCE_DIR}
    PROPERTIES ${properties}
    DISCOVERY_TIMEOUT 120)
endfunction()

# hmc_add_executable(NAME <target> SOURCES ... [DEPS ...])
function(hmc_add_executable)
  cmake_parse_arguments(ARG "" "NAME" "SOURCES;DEPS" ${ARGN})
  add_executable(${ARG_NAME} ${ARG_SOURCES})
  target_include_directories(${ARG_NAME} PRIVATE ${PROJECT_SOURCE_DIR})
  target_link_libraries(${ARG_NAME} PRIVATE ${ARG_DEPS})
  hmc_target_common(${ARG_NAME})
endfunction()
