# Ask the build interpreter where the wheels that carry C++ live, and put
# them on CMAKE_PREFIX_PATH:
#   cmeel-eigen: `python -m cmeel cmake` prints the cmeel prefix(es);
#   lcm:         the folder above the `lcm` package holds lib/lcm/cmake,
#                lib/liblcm.a, include/lcm and bin/lcm-gen;
#   pybind11:    `python -m pybind11 --cmakedir`.
execute_process(
  COMMAND "${Python_EXECUTABLE}" -m cmeel cmake
  OUTPUT_VARIABLE _scrt_cmeel OUTPUT_STRIP_TRAILING_WHITESPACE
  ERROR_QUIET RESULT_VARIABLE _scrt_rc)
if(_scrt_rc EQUAL 0 AND _scrt_cmeel)
  string(REPLACE ":" ";" _scrt_cmeel "${_scrt_cmeel}")
  list(PREPEND CMAKE_PREFIX_PATH ${_scrt_cmeel})
endif()

execute_process(
  COMMAND "${Python_EXECUTABLE}" -c
          "import lcm, os; print(os.path.dirname(os.path.dirname(os.path.abspath(lcm.__file__))))"
  OUTPUT_VARIABLE SCRT_LCM_PREFIX OUTPUT_STRIP_TRAILING_WHITESPACE
  ERROR_QUIET RESULT_VARIABLE _scrt_rc)
if(_scrt_rc EQUAL 0 AND EXISTS "${SCRT_LCM_PREFIX}/lib/lcm/cmake")
  list(PREPEND CMAKE_PREFIX_PATH "${SCRT_LCM_PREFIX}")
else()
  set(SCRT_LCM_PREFIX "")
endif()

execute_process(
  COMMAND "${Python_EXECUTABLE}" -m pybind11 --cmakedir
  OUTPUT_VARIABLE _scrt_pybind11 OUTPUT_STRIP_TRAILING_WHITESPACE
  ERROR_QUIET RESULT_VARIABLE _scrt_rc)
if(_scrt_rc EQUAL 0 AND _scrt_pybind11)
  list(PREPEND CMAKE_PREFIX_PATH "${_scrt_pybind11}")
endif()
