# Read by ctest after the doctest cases are discovered (TEST_INCLUDE_FILES), to
# give whole families of them properties by name. Tests that wait on real
# processes, sockets and heartbeats against deadlines run alone (RUN_SERIAL):
# under `ctest -j` a CPU-heavy neighbour could starve a worker's heartbeat and
# fail them for no fault of the code. New farm tests are covered by their prefix,
# as are the service's end-to-end cases (real broker and worker processes).
foreach(test IN LISTS rayfarm_tests_TESTS)
  if(test MATCHES "^farm: |^replay: a real |^service: |^status routes: a local farm")
    set_tests_properties("${test}" PROPERTIES RUN_SERIAL TRUE)
  endif()
endforeach()
