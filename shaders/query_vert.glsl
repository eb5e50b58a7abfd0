/* Full-screen triangle pair: one fragment per query texel. */
void main()
{
  gl_Position = vec4(pos, 0.0, 1.0);
}
