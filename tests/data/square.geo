// Unit square split along x = 0.5 into two physical surfaces, triangles of size ~0.125.
// Regenerate: gmsh -2 -format msh22 square.geo -o square.msh
// Physical curves as in the built-in box: bottom (y=0) = 1, right (x=1) = 2, top (y=1) = 3, left (x=0) = 4.
// Physical surfaces ("Cell Sets"): 1 = left half x < 0.5, 2 = right half x > 0.5.
h = 0.125;
Point(1) = {0, 0, 0, h};
Point(2) = {0.5, 0, 0, h};
Point(3) = {1, 0, 0, h};
Point(4) = {1, 1, 0, h};
Point(5) = {0.5, 1, 0, h};
Point(6) = {0, 1, 0, h};
Line(1) = {1, 2}; // bottom, left half
Line(2) = {2, 3}; // bottom, right half
Line(3) = {3, 4}; // right
Line(4) = {4, 5}; // top, right half
Line(5) = {5, 6}; // top, left half
Line(6) = {6, 1}; // left
Line(7) = {2, 5}; // interface x = 0.5
Curve Loop(1) = {1, 7, 5, 6};
Plane Surface(1) = {1};
Curve Loop(2) = {2, 3, 4, -7};
Plane Surface(2) = {2};
Physical Curve(1) = {1, 2};
Physical Curve(2) = {3};
Physical Curve(3) = {4, 5};
Physical Curve(4) = {6};
Physical Surface(1) = {1};
Physical Surface(2) = {2};
