// The single doctest binary; every tests/*_test.cpp file adds its cases here.
#define DOCTEST_CONFIG_IMPLEMENT_WITH_MAIN
#include <doctest/doctest.h>
