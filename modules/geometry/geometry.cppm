// peridot.geometry: shapes, constructive solid geometry, cracks and regions.
export module peridot.geometry;
export import :vec;
export import :shapes;
export import :cracks;
