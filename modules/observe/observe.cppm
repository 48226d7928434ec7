// peridot.observe: the observers of a run (see CMakeLists.txt).
export module peridot.observe;
import peridot.std;
export import :progress;
export import :sample;
export import :observers;
