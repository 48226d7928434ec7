// peridot.observe: the observers of a run (see CMakeLists.txt).
export module peridot.observe;
export import :progress;
export import :sample;
export import :observers;
