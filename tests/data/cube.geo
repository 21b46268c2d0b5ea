// Unit cube, tetrahedra of size ~0.35.
// Regenerate: gmsh -3 -format msh22 cube.geo -o cube.msh
// Physical surfaces as in the built-in box: bottom (z=0) = 1, top (z=1) = 2, front (y=0) = 3,
// back (y=1) = 4, right (x=1) = 5, left (x=0) = 6. Physical volume ("Cell Sets") 1.
SetFactory("Built-in");
h = 0.35;
Point(1) = {0, 0, 0, h};
Point(2) = {1, 0, 0, h};
Point(3) = {1, 1, 0, h};
Point(4) = {0, 1, 0, h};
Point(5) = {0, 0, 1, h};
Point(6) = {1, 0, 1, h};
Point(7) = {1, 1, 1, h};
Point(8) = {0, 1, 1, h};
Line(1) = {1, 2};
Line(2) = {2, 3};
Line(3) = {3, 4};
Line(4) = {4, 1};
Line(5) = {5, 6};
Line(6) = {6, 7};
Line(7) = {7, 8};
Line(8) = {8, 5};
Line(9) = {1, 5};
Line(10) = {2, 6};
Line(11) = {3, 7};
Line(12) = {4, 8};
Curve Loop(1) = {1, 2, 3, 4};      // bottom z = 0
Plane Surface(1) = {1};
Curve Loop(2) = {5, 6, 7, 8};      // top z = 1
Plane Surface(2) = {2};
Curve Loop(3) = {1, 10, -5, -9};   // front y = 0
Plane Surface(3) = {3};
Curve Loop(4) = {3, 12, -7, -11};  // back y = 1
Plane Surface(4) = {4};
Curve Loop(5) = {2, 11, -6, -10};  // right x = 1
Plane Surface(5) = {5};
Curve Loop(6) = {4, 9, -8, -12};   // left x = 0
Plane Surface(6) = {6};
Surface Loop(1) = {1, 2, 3, 4, 5, 6};
Volume(1) = {1};
Physical Surface(1) = {1};
Physical Surface(2) = {2};
Physical Surface(3) = {3};
Physical Surface(4) = {4};
Physical Surface(5) = {5};
Physical Surface(6) = {6};
Physical Volume(1) = {1};
