#include "coupler/coupler.h"

int main(int argc, char **argv) { return cpl_main(argc, argv); }
