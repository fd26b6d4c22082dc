// The translation unit that the precompiled headers of cmake/PcrPrecompiledHeaders.cmake are
// built for; the targets reuse them. It defines nothing.
