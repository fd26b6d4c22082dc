#pragma once
// The library's log: everything below the application (src/app) logs through Logger(), a spdlog
// logger of the library's own, never through spdlog's default logger, which belongs to the
// application that embeds the library.
#include <spdlog/logger.h>
#include <spdlog/sinks/sink.h>

#include <memory>

namespace pcr {

// The library's logger ("pcr", not in spdlog's registry). Its level filters the library's lines
// only (default info; spdlog::set_level does not change it). Where its lines go is the log
// target's choice (SetLogTarget): by default each line is handed on to spdlog's default logger of
// the moment, whose own level, pattern and sinks then apply to it as to the application's lines.
// Thread-safe, as spdlog loggers are; lives to the end of the process.
spdlog::logger& Logger();

// Sends the library's lines to `target` alone (its formatter and level apply; the library
// logger's level first), leaving spdlog's default logger as it is; null hands them on to spdlog's
// default logger again. Thread-safe: may be called while lines are logged.
void SetLogTarget(std::shared_ptr<spdlog::sinks::sink> target);

}  // namespace pcr
