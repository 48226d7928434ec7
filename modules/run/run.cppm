// peridot.run: the run, written once. A Problem becomes a Simulation by the one composition
// switch; each flavour is a small stepper (explicit step, Newmark step, load increment, static
// solve), and one loop drives any of them: advance, observe on cadence, checkpoint, progress,
// stop request, finish or fail. N ranks wrap the explicit stepper; they are not a second loop.
export module peridot.run;
import peridot.std;
export import peridot.problem;
export import peridot.observe;
export import :stop;
export import :loop;
export import :parts;
export import :checkpointing;
export import :explicit_stepper;
export import :implicit_steppers;
export import :static_steppers;
export import :distributed;
export import :simulation;
