// peridot.geometry: shapes, constructive solid geometry, cracks and regions; exact sums.
export module peridot.geometry;
import peridot.std;
export import :vec;
export import :shapes;
export import :cracks;
export import :exact_sum;
