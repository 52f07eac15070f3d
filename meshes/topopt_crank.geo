// The crank of cases/slider_crank_links_topopt: the plate link of topopt_rod.geo at L = 0.15 m
// between pin centres (40 mm deep, 10 mm thick, bosses of radius 20 mm, pin holes of radius
// 6 mm). Physical groups as there: volumes "design" (30 mm < x < 120 mm) and "boss"; surfaces
// "pin_a" (the hole at the origin) and "pin_b" (the hole at x = 0.15 m).
L = 0.15;
Include "topopt_rod.geo";
