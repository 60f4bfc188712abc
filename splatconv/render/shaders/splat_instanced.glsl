// The viewer's inputs: a quad corner per vertex, the splat's index per instance.
in vec2 position;
in int index;
