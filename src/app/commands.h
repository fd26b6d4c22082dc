#pragma once
// Subcommands of the pcr_orb executable. Each Add*Command registers one CLI11 subcommand whose
// callback does the work; errors are thrown (pcr::InputError, pcr::ConfigError, std::exception)
// and reported once by Main().
#include <CLI/CLI.hpp>
#include <string>

namespace pcr::app {

void AddInfoCommand(CLI::App& app);      // cmd_info.cpp: describe a KITTI sequence / raw drive
void AddEvalCommand(CLI::App& app);      // cmd_eval.cpp: ATE / RPE / KITTI metrics
void AddSynthCommand(CLI::App& app);     // cmd_synth.cpp: write a synthetic KITTI-format sequence
void AddRunCommand(CLI::App& app);       // cmd_run.cpp: SLAM on a dataset
void AddPipelineCommand(CLI::App& app);  // cmd_pipeline.cpp: the TBB flow-graph pipeline
void AddVocabCommand(CLI::App& app);     // cmd_vocab.cpp: train the place-recognition vocabulary

// --raw-truth (run, pipeline, info): a raw drive's ground-truth positions, "ins" or "gps"
// (pcr::ParseRawTruth); *raw_truth holds the default.
void AddRawTruthOption(CLI::App* cmd, std::string* raw_truth);

// A check for an unsigned 64-bit option (a seed): a whole number from 0 to 2^64-1. CLI11 reads
// "-1" into an unsigned option as 2^64-1.
CLI::Validator UnsignedWhole64();

// A check for an int option: a whole number from min to INT_MAX. (CLI::PositiveNumber refuses 0
// saying "Value 0 not in range 0.000000 to 1797693...".)
CLI::Validator WholeFrom(int min);

// Runs the command line; returns the process exit code.
int Main(int argc, char** argv);

}  // namespace pcr::app
