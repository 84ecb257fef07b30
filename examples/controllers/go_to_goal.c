/* A go-to-goal controller for vl, interface version 1 (docs/controllers.md).
 *
 * Heads for the goal; when something blocks the way it follows the
 * obstacle's edge, on the side its sensors choose, until the goal lies
 * on the free side (a simple Bug algorithm). No libc: build with
 *
 *   clang --target=wasm32 -nostdlib -O2 -Wl,--no-entry -Wl,--export-dynamic \
 *         -o go_to_goal.wasm go_to_goal.c
 */

#define EXPORT __attribute__((visibility("default")))

static double observation[32];
static double command[2];

/* The robot's wheel base, mm (the Khepera II's). */
#define WHEEL_BASE 53.0
/* Close enough to the goal, mm. */
#define ARRIVED 10.0
/* Speeds, mm/s. */
#define CRUISE 120.0
#define ALONG_EDGE 70.0
/* Proximity readings (0–1023, higher is nearer): something ahead closer
 * than about 35 mm blocks the way; an edge is followed at about 40 mm. */
#define BLOCKED 220.0
#define EDGE 180.0
/* An edge is followed for at most this long, s, before trying the goal again. */
#define LONGEST_FOLLOW 25.0

/* 0: heading for the goal; +1: following an edge on the left; -1: on the right. */
static int follow = 0;
static double followed_since = 0.0;

EXPORT int vl_abi(void) { return 1; }
EXPORT int vl_observation(void) { return (int)observation; }
EXPORT int vl_command(void) { return (int)command; }

/* sin on any angle, by its Taylor series to x^11 on [-pi, pi]: within 3e-4. */
static double sine(double x) {
    const double pi = 3.14159265358979;
    while (x > pi) x -= 2 * pi;
    while (x < -pi) x += 2 * pi;
    double x2 = x * x, term = x, sum = x;
    for (int n = 1; n <= 5; n++) {
        term *= -x2 / ((2 * n) * (2 * n + 1));
        sum += term;
    }
    return sum;
}

static double cosine(double x) { return sine(x + 1.5707963267949); }

static double clamp(double x, double lo, double hi) {
    return x < lo ? lo : x > hi ? hi : x;
}

static double most(double a, double b) { return a > b ? a : b; }

static void wheels(double v, double w) {
    command[0] = v - w * WHEEL_BASE / 2;
    command[1] = v + w * WHEEL_BASE / 2;
}

EXPORT int vl_step(void) {
    double t = observation[0];
    double x = observation[1], y = observation[2], theta = observation[3];
    double gx = observation[7], gy = observation[8];
    double limit = observation[18];
    const double *ir = &observation[9]; /* 0 left … 5 right, 6–7 behind */
    wheels(0, 0);
    if (gx != gx || gy != gy) return 1; /* no goal (NaN): nothing to do */
    double dx = gx - x, dy = gy - y;
    double dist = __builtin_sqrt(dx * dx + dy * dy);
    if (dist < ARRIVED) return 1;
    /* The goal's direction in the robot's frame, as a unit vector. */
    double c = cosine(theta), s = sine(theta);
    double ahead = (c * dx + s * dy) / dist, left = (-s * dx + c * dy) / dist;
    double front = most(ir[2], ir[3]);
    double on_left = ir[0] + ir[1] + ir[2], on_right = ir[3] + ir[4] + ir[5];

    if (follow == 0 && ahead > 0 && (front > BLOCKED || most(ir[1], ir[4]) > 2 * BLOCKED)) {
        /* Blocked: keep the obstacle on the side that sees more of it. */
        follow = on_left > on_right ? 1 : -1;
        followed_since = t;
    }
    if (follow != 0) {
        /* The goal lies on the free side, the way ahead is clear: leave. */
        int free = follow * left < -0.2 && front < BLOCKED / 2;
        if (free || t - followed_since > LONGEST_FOLLOW) follow = 0;
    }
    if (follow != 0) {
        double side = follow > 0 ? ir[0] + 0.7 * ir[1] : ir[5] + 0.7 * ir[4];
        if (front > BLOCKED || (follow > 0 ? ir[1] : ir[4]) > 2 * BLOCKED) {
            wheels(0, -follow * 2.0); /* turn away on the spot */
        } else {
            /* Nearer than the edge distance: turn away; further: turn in. */
            double error = clamp((EDGE - side) / EDGE, -1.0, 1.0);
            wheels(clamp(ALONG_EDGE, 0, limit), follow * 2.0 * error);
        }
        return 0;
    }
    double speed = clamp(CRUISE, 0.0, limit);
    speed = clamp(speed, 0.0, 2.0 * dist + 20.0); /* slow into the goal */
    double v = ahead > 0 ? speed * ahead : 0.0;
    double w = 3.0 * left + (ahead < 0 ? (left >= 0 ? 2.0 : -2.0) : 0.0);
    wheels(v, w);
    return 0;
}
