// The rocker of cases/fourbar_topopt: the plate link of topopt_rod.geo at L = 0.25 m between
// pin centres (40 mm deep, 10 mm thick, bosses of radius 20 mm, pin holes of radius 6 mm).
// Physical groups as there: volumes "design" (30 mm < x < 220 mm) and "boss"; surfaces "pin_a"
// (the hole at the origin) and "pin_b" (the hole at x = 0.25 m).
L = 0.25;
Include "topopt_rod.geo";
