#include "cli/cli.h"

int main(int argc, char** argv) { return propcam::firmware::run_cli(argc, argv); }
