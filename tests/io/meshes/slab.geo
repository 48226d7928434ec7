// A 1 x 0.5 x 0.25 m slab, extruded from its z = 0 face, with named faces and volume.
Point(1) = {0, 0, 0, 0.2}; Point(2) = {1, 0, 0, 0.2}; Point(3) = {1, 0.5, 0, 0.2}; Point(4) = {0, 0.5, 0, 0.2};
Line(1) = {1, 2}; Line(2) = {2, 3}; Line(3) = {3, 4}; Line(4) = {4, 1};
Curve Loop(1) = {1, 2, 3, 4}; Plane Surface(1) = {1};
out[] = Extrude {0, 0, 0.25} { Surface{1}; };
Physical Surface("back") = {1};
Physical Surface("front") = {out[0]};
Physical Surface("left") = {out[5]};
Physical Volume("solid") = {out[1]};
