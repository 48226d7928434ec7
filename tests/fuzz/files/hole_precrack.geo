// Seed 003 Sec. 4.5 (paper Sec. 7.7, Fig. 18, after Dai et al. 2015, Fig. 18): rectangle
// with a horizontal edge pre-crack and a circular hole near its path, pulled apart by its
// top and bottom layers. Coordinates in metres (Peridot reads SI).
//
// The paper gives the setup only in Fig. 18, which we do not have. Assumed (all in mm):
//  - plate 50 wide (x) and 40 tall (y): with the paper's eps = 0.4, h = 0.1 that is about
//    2.3e5 nodes, the size the paper's small h suggests; the coarse deck (eps = 2) still has
//    20 horizons across the height;
//  - pre-crack along y = 20 (mid-height) from the left edge to x = 10 (a/W = 0.2); it is a
//    line of cut bonds given in the decks (geometry.cracks), not a slit in this mesh;
//  - hole radius R = 2.5 centred at (25, 29): 15 ahead of the pre-crack tip and 9 (3.6 R)
//    above the crack line, so its bottom is 6.5 above the line and its top 9 below the
//    top edge. Chosen by trial at the coarse eps = 2: with the hole 6 or 7 above the line
//    (R = 3 at y = 21, R = 2.5 at y = 22 in a 30 mm tall plate) the crack turned into the
//    hole and a second crack started from the hole's far side; at 9 above it bends toward the
//    hole, passes beneath it and goes on horizontally, as the paper describes (Sec. 7.7);
//  - loaded layers: the top and bottom slabs of the bounding box, thickness eps, in the decks.
// Physical group: "body".
// Mesh size: set by the deck (mesh.size); the value below is only for meshing it alone.
SetFactory("OpenCASCADE");

W = 0.050;   // plate width [m]
H = 0.040;   // plate height [m]
R = 0.0025;  // hole radius [m]
xc = 0.025;  // hole centre [m]
yc = 0.029;

Rectangle(1) = {0, 0, 0, W, H};
Disk(2) = {xc, yc, 0, R, R};
BooleanDifference(3) = { Surface{1}; Delete; }{ Surface{2}; Delete; };

Physical Surface("body") = {3};

Mesh.MeshSizeMin = 0.1e-3;
Mesh.MeshSizeMax = 0.1e-3;
