#include "app/commands.h"

int main(int argc, char** argv) { return pcr::app::Main(argc, argv); }
