//! OSPA and GOSPA.
