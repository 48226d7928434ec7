// The plate with a central hole of circular_hole.geo as a solid 6 mm thick, meshed with
// tetrahedra: 100 x 100 x 6 mm, hole radius 10 mm through the thickness, 3 mm loaded layers
// at x <= 3 mm and x >= 97 mm. Coordinates in metres.
// Physical groups: "body" (all of it), "left_layer" and "right_layer" (volumes, separate by
// boolean fragments so their nodes are an exact set and the mesh conforms at x = 3 and 97 mm).
// Mesh size: set by the deck (mesh.size); the value below is only for meshing it alone.
SetFactory("OpenCASCADE");

W = 0.100;   // plate side [m]
R = 0.010;   // hole radius [m]
T = 0.003;   // loaded layer thickness [m]
D = 0.006;   // plate thickness [m]

Box(1) = {0, 0, 0, W, W, D};
Cylinder(2) = {W / 2, W / 2, 0, 0, 0, D, R};
BooleanDifference(3) = { Volume{1}; Delete; }{ Volume{2}; Delete; };
Box(4) = {0, 0, 0, T, W, D};
Box(5) = {W - T, 0, 0, T, W, D};
all() = BooleanFragments{ Volume{3}; Delete; }{ Volume{4, 5}; Delete; };

tol = 1.0e-6;
left() = Volume In BoundingBox{-tol, -tol, -tol, T + tol, W + tol, D + tol};
right() = Volume In BoundingBox{W - T - tol, -tol, -tol, W + tol, W + tol, D + tol};

Physical Volume("body") = {all()};
Physical Volume("left_layer") = {left()};
Physical Volume("right_layer") = {right()};

Mesh.MeshSizeMin = 2.0e-3;
Mesh.MeshSizeMax = 2.0e-3;
