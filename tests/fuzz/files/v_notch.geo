// Seed 003 Sec. 4.4 (paper Sec. 7.6, Fig. 15): rectangular beam with a V-notch, in bending.
// Coordinates in metres (Peridot reads SI).
//
// The paper gives the setup only in Fig. 15, which we do not have. Assumed (all in mm):
//  - beam 100 long (x) and 30 deep (y), x in [0, 100], y in [0, 30]: a span/depth ratio of 3,
//    a stubby three-point-bending beam that bends without buckling;
//  - V-notch at mid-span on the bottom (tension) edge, opposite the loaded part of the top
//    edge, as in a three-point-bending specimen: depth 10 (a/H = 1/3), opening angle 60 deg
//    (mouth 11.55 wide), sharp tip at (50, 10). The ligament above the tip is 20 = 20 eps
//    at the paper's eps = 1 (10 eps at the coarse deck's eps = 2);
//  - the supports (bottom, near both ends) and the loaded strip (top, around x = 50) are
//    rectangles in the decks, not groups here, so that they can be changed without remeshing.
// Physical group: "body".
// Mesh size: set by the deck (mesh.size); the value below is only for meshing it alone.

L = 0.100;                      // beam length [m]
H = 0.030;                      // beam depth [m]
a = 0.010;                      // notch depth [m]
half = a * Tan(30 * Pi / 180);  // half of the notch mouth (60 deg opening) [m]

Point(1) = {0, 0, 0};
Point(2) = {L / 2 - half, 0, 0};
Point(3) = {L / 2, a, 0};       // notch tip
Point(4) = {L / 2 + half, 0, 0};
Point(5) = {L, 0, 0};
Point(6) = {L, H, 0};
Point(7) = {0, H, 0};

Line(1) = {1, 2};
Line(2) = {2, 3};
Line(3) = {3, 4};
Line(4) = {4, 5};
Line(5) = {5, 6};
Line(6) = {6, 7};
Line(7) = {7, 1};
Curve Loop(1) = {1, 2, 3, 4, 5, 6, 7};
Plane Surface(1) = {1};

Physical Surface("body") = {1};

Mesh.MeshSizeMin = 0.25e-3;
Mesh.MeshSizeMax = 0.25e-3;
