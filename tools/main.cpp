// The qota command: one executable, one subcommand per tool (tools/cli.cpp parses, each tool is a
// library function in qota_tools.hpp).
#include <iostream>

#include "qota_tools.hpp"

int main(int argc, char** argv) { return qota::tools::runCli(argc, argv, std::cin, std::cout, std::cerr); }
