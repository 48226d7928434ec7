// Seed 003 Sec. 4.3 (paper Sec. 7.5, Fig. 12): square plate with a central circular hole,
// pulled along x by its left and right layers. Coordinates in metres (Peridot reads SI).
//
// The paper gives the setup only in Fig. 12, which we do not have. Assumed (all in mm):
//  - plate 100 x 100: the same square as the paper's Mode-I example (Sec. 7.4, D = [0, 100]^2),
//    so that the two velocity-driven examples share a size;
//  - hole radius R = 10 (diameter 20 = W/5) centred at (50, 50): large against the paper's
//    eps = 1 (R = 10 eps) so the hole's stress concentration (Kirsch factor 3 at the top and
//    bottom points, about 3.1 for D/W = 0.2) is resolved, and still resolved at the coarse
//    deck's eps = 2 (R = 5 eps);
//  - left/right loaded layers 3 mm thick over the full height: Sec. 7.4.2 fixes the
//    Mode-I layers at 3 mm independent of eps; we do the same so that the paper deck
//    (eps = 1) and the coarse deck (eps = 2) pull on the same material.
// Physical groups: "body" (all of it), "left_layer" (x <= 3), "right_layer" (x >= 97).
// The layers are separate surfaces (boolean fragments), so their nodes are an exact set and
// the mesh conforms along x = 3 and x = 97.
// Mesh size: set by the deck (mesh.size); the value below is only for meshing it alone.
SetFactory("OpenCASCADE");

W = 0.100;   // plate side [m]
R = 0.010;   // hole radius [m]
T = 0.003;   // loaded layer thickness [m]

Rectangle(1) = {0, 0, 0, W, W};
Disk(2) = {W / 2, W / 2, 0, R, R};
BooleanDifference(3) = { Surface{1}; Delete; }{ Surface{2}; Delete; };
Rectangle(4) = {0, 0, 0, T, W};
Rectangle(5) = {W - T, 0, 0, T, W};
all() = BooleanFragments{ Surface{3}; Delete; }{ Surface{4, 5}; Delete; };

tol = 1.0e-6;
left() = Surface In BoundingBox{-tol, -tol, -tol, T + tol, W + tol, tol};
right() = Surface In BoundingBox{W - T - tol, -tol, -tol, W + tol, W + tol, tol};

Physical Surface("body") = {all()};
Physical Surface("left_layer") = {left()};
Physical Surface("right_layer") = {right()};

Mesh.MeshSizeMin = 0.25e-3;
Mesh.MeshSizeMax = 0.25e-3;
